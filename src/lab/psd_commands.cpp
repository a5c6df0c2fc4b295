#include "psd_commands.h"

#include <fmt/printf.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "zerocal/daemon/config.h"
#include "zerocal/error.h"
#include "zerocal/psd/psd.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/sim/psd_rig.h"
#include "zerocal/usb1408fs/libusb_transport.h"
#include "zerocal/usb1408fs/usb1408fs_kind.h"

namespace zerocal::lab {
namespace {

std::string format(const char* spec, double a, double b = 0, double c = 0, double d = 0) {
  return fmt::sprintf(spec, a, b, c, d);
}

// A map for `psd --sim` when the configuration has none: fitted from a simulated sweep with
// another noise seed than the live readings, as a rig's map comes from an earlier sweep.
psd::PsdMap mapFromSimulatedSweep(const usb1408fs::BoardSettings& board, std::uint32_t seed) {
  sim::SimulatedPsdRig rig(seed + 1000, board.channels);
  return psd::PsdMap::fit(sim::simulateSweep(rig, sim::SweepOptions{}), psd::MapFitOptions{});
}

nlohmann::json orNull(bool have, double value) {
  return have ? nlohmann::json(value) : nlohmann::json(nullptr);
}

}  // namespace

void addPsdCommands(CLI::App& app, PsdCommands& c) {
  c.sweep = app.add_subcommand("psd-sweep",
                               "record a stage sweep of the PSD as CSV on stdout (for psd-map)");
  c.sweep->add_flag("--sim", c.sweep_args.sim,
                    "simulated PSD and USB-1408FS (required: a real sweep needs the stage)");
  c.sweep->add_option("--seed", c.sweep_args.seed, "noise seed of the simulated PSD")
      ->default_val(c.sweep_args.seed);
  c.sweep->add_option("--step", c.sweep_args.step_mm, "stage step, mm")
      ->default_val(c.sweep_args.step_mm);
  c.sweep->add_option("--extent", c.sweep_args.extent_mm, "the stage covers +-MM on both axes")
      ->default_val(c.sweep_args.extent_mm);

  c.map = app.add_subcommand(
      "psd-map", "fit the PSD's voltage->mm map from a sweep, report residuals and valid zone");
  c.map->add_option("sweep", c.map_args.sweep_file, "sweep CSV: u_mm,v_mm,x_v,y_v,sum_v")
      ->required();
  c.map->add_option("--out", c.map_args.out_file,
                    "write the map as YAML for the configuration (daq.map_file)");
  c.map->add_flag("--json", c.map_args.json, "print one JSON object instead of text");
  c.map->add_option("--degree", c.map_args.degree, "total degree of the polynomial")
      ->default_val(c.map_args.degree)
      ->check(CLI::Range(1, 12));
  c.map->add_option("--zone", c.map_args.zone_mm, "fit the points within +-MM on both axes")
      ->default_val(c.map_args.zone_mm)
      ->check(CLI::PositiveNumber);
  c.map->add_option("--min-sum", c.map_args.min_sum_v, "ignore points with less SUM, volts")
      ->default_val(c.map_args.min_sum_v);

  c.live = app.add_subcommand("psd", "live PSD readings: spot position in mm, SUM, valid or not");
  c.live->add_flag("--sim", c.live_args.sim,
                   "simulated PSD and board through the same USB-1408FS protocol code");
  c.live->add_option("--config", c.live_args.config_file,
                     "YAML with a daq: section: zerocald's configuration file, or config/psd.yaml; "
                     "default: zerocald's daq defaults (channels 0, 1, 2 differential +-5 V, 100 "
                     "samples at 1 kHz, no map: volts only)");
  c.live->add_option("--count", c.live_args.count, "number of readings")
      ->default_val(c.live_args.count)
      ->check(CLI::Range(1, 1000000));
  c.live->add_flag("--json", c.live_args.json, "one JSON object per reading");
  c.live->add_option("--sim-spot", c.live_args.sim_spot, "simulated spot position U V, mm")
      ->expected(2)
      ->needs(c.live->get_option("--sim"));
  c.live->add_flag("--sim-dark", c.live_args.sim_dark, "simulated: no light on the PSD")
      ->needs(c.live->get_option("--sim"));
  c.live->add_option("--seed", c.live_args.seed, "noise seed of the simulated PSD")
      ->default_val(c.live_args.seed)
      ->needs(c.live->get_option("--sim"));
}

int runPsdSweep(const PsdSweepArgs& args) {
  if (!args.sim) {
    throw InputError(
        "psd-sweep records simulated sweeps only (--sim): a sweep on the real rig needs the stage "
        "moved by hand or by its own controller; docs/psd.md says how to record one");
  }
  if (!(args.step_mm > 0) || !(args.extent_mm > 0)) {
    throw InputError("the sweep step and extent must be positive");
  }
  if (2 * args.extent_mm / args.step_mm > 400) {
    throw InputError("the sweep would have more than 401 positions per axis; use a larger step");
  }
  sim::SimulatedPsdRig rig(args.seed);
  sim::SweepOptions options;
  options.step_mm = args.step_mm;
  options.extent_mm = args.extent_mm;
  psd::writeSweepCsv(std::cout, sim::simulateSweep(rig, options));
  return 0;
}

int runPsdMap(const PsdMapArgs& args) {
  std::ifstream in(args.sweep_file);
  if (!in) throw InputError(args.sweep_file + ": cannot open the sweep file");
  const auto sweep = psd::readSweepCsv(in, args.sweep_file);
  psd::MapFitOptions options;
  options.degree = args.degree;
  options.zone_half_width_mm = args.zone_mm;
  options.min_sum_v = args.min_sum_v;
  psd::MapFitReport report;
  const psd::PsdMap map = psd::PsdMap::fit(sweep, options, &report);

  std::ostringstream comment;
  comment << "zerocal psd-map " << args.sweep_file << ": degree " << args.degree << ", "
          << report.points_used << " points, residuals RMS "
          << format("%.3f um, max %.3f um", report.rms_residual_mm * 1e3,
                    report.max_residual_mm * 1e3);
  const std::string yaml = psd::psdMapToYaml(map, comment.str());
  if (!args.out_file.empty()) {
    std::ofstream out(args.out_file);
    out << yaml;
    if (!out) throw InputError(args.out_file + ": cannot write the map");
  }
  if (args.json) {
    nlohmann::json j;
    j["sweep"] = args.sweep_file;
    j["points_total"] = sweep.size();
    j["points_used"] = report.points_used;
    j["degree"] = args.degree;
    j["rms_residual_um"] = report.rms_residual_mm * 1e3;
    j["max_residual_um"] = report.max_residual_mm * 1e3;
    j["zone_mm"] = {{"u", {report.u_min, report.u_max}}, {"v", {report.v_min, report.v_max}}};
    j["out"] = args.out_file.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.out_file);
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::cout << "PSD map from " << args.sweep_file << ": degree " << args.degree << ", "
            << report.points_used << " of " << sweep.size() << " points used (within +-"
            << args.zone_mm << " mm, SUM >= " << args.min_sum_v << " V)\n"
            << format("fit residuals: RMS %.3f um, max %.3f um\n", report.rms_residual_mm * 1e3,
                      report.max_residual_mm * 1e3)
            << format("valid zone: u %+.3f .. %+.3f mm, v %+.3f .. %+.3f mm\n", report.u_min,
                      report.u_max, report.v_min, report.v_max);
  if (args.out_file.empty()) {
    std::cout << "\n" << yaml;
  } else {
    std::cout << "map written to " << args.out_file << "\n";
  }
  return 0;
}

int runPsd(const PsdArgs& args) {
  // The daemon's daq section, read and checked as the daemon reads it; without a file, its
  // defaults.
  const DaqConfig daq_section =
      args.config_file.empty() ? DaqConfig{} : loadDaqSection(args.config_file);
  const psd::PsdConfig& config = daq_section.psd;
  // This command reads the USB-1408FS, whichever board the file's daq.kind names.
  const usb1408fs::BoardSettings& settings = usb1408fs::boardSettingsOf(daq_section.boards);
  std::optional<psd::PsdMap> map;
  if (!config.map_file.empty()) map = psd::loadPsdMap(config.map_file);
  if (!map && args.sim) {
    std::cerr << "zerocal: no map configured; using one fitted from a simulated sweep\n";
    map = mapFromSimulatedSweep(settings, args.seed);
  }

  // The simulated rig and the real board meet at the same Usb1408fs: only the transport differs.
  std::unique_ptr<sim::SimulatedPsdRig> rig;
  std::unique_ptr<usb1408fs::Usb1408fs> board;
  usb1408fs::Usb1408fs* daq = nullptr;
  if (args.sim) {
    rig = std::make_unique<sim::SimulatedPsdRig>(args.seed, settings.channels);
    if (args.sim_dark) {
      rig->setSpot(std::nullopt);
    } else {
      rig->setSpot(PsdSpot{args.sim_spot[0], args.sim_spot[1]});
    }
    daq = &rig->daq();
  } else {
    const std::string serial = settings.serial;
    board = std::make_unique<usb1408fs::Usb1408fs>(
        [serial] { return usb1408fs::LibusbTransport::open(serial); });
    daq = board.get();
  }
  // Said once the board is open, so that a missing board is the only message when it is absent.
  if (!map) {
    std::cerr << "zerocal: no map configured (map_file in the daq: section): volts only\n";
  }

  const auto samples = static_cast<std::size_t>(settings.samples_per_reading);
  usb1408fs::PsdStream stream(*daq, settings.channels, samples, settings.scan_rate_hz);
  psd::SpotDetector detector(config.sum_threshold_v, config.sumOffThresholdV());
  // Twice a block's acquisition plus USB latency: a missing reading means the board stalled.
  const auto timeout = std::chrono::milliseconds(
      100 + static_cast<long>(2000.0 * static_cast<double>(samples) / settings.scan_rate_hz));
  for (std::size_t k = 0; k < args.count; ++k) {
    psd::VoltageReading r;
    if (!stream.next(r, timeout)) {
      throw usb1408fs::TimeoutError("no PSD reading from the USB-1408FS within " +
                                    std::to_string(timeout.count()) + " ms");
    }
    const bool present = detector.update(r);
    PsdReading p;
    if (map) p = map->apply(r);
    const bool have_uv = map && present && p.spot_present;
    const bool valid = have_uv && p.in_valid_zone;
    if (args.json) {
      nlohmann::json j;
      j["reading"] = k;
      j["u_mm"] = orNull(have_uv, p.spot.u_mm);
      j["u_se_mm"] = orNull(have_uv, p.se.u_mm);
      j["v_mm"] = orNull(have_uv, p.spot.v_mm);
      j["v_se_mm"] = orNull(have_uv, p.se.v_mm);
      j["x_v"] = r.x;
      j["y_v"] = r.y;
      j["sum_v"] = r.sum;
      j["sum_se_v"] = r.sum_se;
      j["samples"] = r.samples;
      j["spot_present"] = present;
      j["in_valid_zone"] = valid;
      std::cout << j.dump() << std::endl;
      continue;
    }
    std::string line;
    if (have_uv) {
      line = format("u %+.5f mm +-%.5f  v %+.5f mm +-%.5f  ", p.spot.u_mm, p.se.u_mm, p.spot.v_mm,
                    p.se.v_mm);
    } else {
      line = format("X %+.5f V  Y %+.5f V  ", r.x, r.y);
    }
    line += format("SUM %.4f V  ", r.sum);
    if (!present) {
      line += "no spot";
    } else if (!map) {
      line += "spot present";
    } else if (!p.spot_present) {
      line += "spot present, too little light for the map (SUM below its min_sum_v)";
    } else {
      line += valid ? "spot present, in the valid zone" : "spot present, OUTSIDE the valid zone";
    }
    // endl: a person watching the rig wants each reading as it comes, not in a buffered batch.
    std::cout << line << std::endl;
  }
  return 0;
}

}  // namespace zerocal::lab
