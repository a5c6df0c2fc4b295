// zerocal-lab experiment remount: per seeded world a reference, then one restore per re-mount
// (the PSD or the laser taken off and put back, moved or turned by a given size in a direction
// drawn from the world's seed), each a session of its own in the world's data folder with the
// same motor replacement; per re-mount, how good the restored changes still are and how often
// the restore refuses them.
#include "remount_experiment.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "cell_experiment.h"
#include "experiment_sessions.h"
#include "zerocal/error.h"
#include "zerocal/sim/remount.h"
#include "zerocal/sim/world.h"
#include "zerocal/sim/zero_change.h"

namespace zerocal::lab {
namespace {

using Json = nlohmann::json;
constexpr const char* kOrigin = "zerocal-lab experiment remount";

enum class Mounted { kNone, kPsdMoved, kPsdTurned, kLaserMoved, kLaserTurned };

struct RemountCase {
  Mounted what = Mounted::kNone;
  double size = 0;  // mm for a move, deg for a turn
};

std::string caseName(Mounted what) {
  switch (what) {
    case Mounted::kNone:
      return "none";
    case Mounted::kPsdMoved:
      return "PSD moved";
    case Mounted::kPsdTurned:
      return "PSD turned";
    case Mounted::kLaserMoved:
      return "laser moved";
    case Mounted::kLaserTurned:
      return "laser turned";
  }
  return "?";
}

const char* unitOf(Mounted what) {
  return what == Mounted::kPsdTurned || what == Mounted::kLaserTurned ? "deg" : "mm";
}

// What a case's restores gave, summed over the worlds.
struct CaseFigures {
  int restores = 0, usable = 0, told_moved = 0, wrong_usable = 0;
  int estimates = 0, beyond = 0, covered = 0, usable_estimates = 0;
  double sq = 0, usable_sq = 0, worst_sigmas = 0;
};

DaemonConfig configOf(const RemountExperimentArgs& args) {
  std::vector<std::string> problems;
  const auto sizes = [&](const char* name, const std::vector<double>& v, double hi) {
    for (const double s : v)
      if (!(s > 0 && s <= hi))
        problems.push_back(
            fmt::format(FMT_STRING("{}: {} given, each must be within (0, {}]"), name, s, hi));
  };
  sizes("--psd-moved-mm", args.psd_moved_mm, kMaxRemountMm);
  sizes("--psd-turned-deg", args.psd_turned_deg, kMaxRemountDeg);
  sizes("--laser-moved-mm", args.laser_moved_mm, kMaxRemountMm);
  sizes("--laser-turned-deg", args.laser_turned_deg, kMaxRemountDeg);
  if (!(args.warm_s >= 0 && args.warm_s <= kMaxWarmS))
    problems.push_back(fmt::format(FMT_STRING("--warm-s: {} given, must be within 0..{}"),
                                   args.warm_s, kMaxWarmS));
  if (!(args.restore_min_deg > 0 && args.restore_min_deg <= args.restore_max_deg &&
        args.restore_max_deg <= kMaxZeroChangeDeg))
    problems.push_back(fmt::format(
        FMT_STRING("--restore-change-min and -max: {}..{} given, must be within (0, {}] and in "
                   "order"),
        args.restore_min_deg, args.restore_max_deg, kMaxZeroChangeDeg));
  return experimentConfig(
      kOrigin, args.ideal_world, args.overrides,
      {"backend.kind", "backend.sim_seed", "backend.sim_world", "backend.sim_warm_s",
       "backend.sim_zero_change_joint", "backend.sim_zero_change_deg", "backend.sim_psd_moved_mm",
       "backend.sim_psd_turned_deg", "backend.sim_laser_moved_mm", "backend.sim_laser_turned_deg",
       "session.data_dir"},
      "the world from --seed0 and --worlds, the arm's warm-up from --warm-s, the re-mounts from "
      "--psd-moved-mm, --psd-turned-deg, --laser-moved-mm and --laser-turned-deg",
      problems);
}

std::vector<RemountCase> casesOf(const RemountExperimentArgs& args) {
  std::vector<RemountCase> cases{{Mounted::kNone, 0}};
  for (const double s : args.psd_moved_mm) cases.push_back({Mounted::kPsdMoved, s});
  for (const double s : args.psd_turned_deg) cases.push_back({Mounted::kPsdTurned, s});
  for (const double s : args.laser_moved_mm) cases.push_back({Mounted::kLaserMoved, s});
  for (const double s : args.laser_turned_deg) cases.push_back({Mounted::kLaserTurned, s});
  return cases;
}

// The case's re-mount in a direction drawn from the world's seed, its kind and its size (not its
// place in the list, so that a size measured alone is the same re-mount): a move of `size`
// mm along a random unit vector, or a turn of `size` deg about a random axis (as roll, pitch, yaw
// of size times the axis: for turns of a few degrees the same rotation within 1e-4 of its angle).
void setRemount(const RemountCase& c, std::uint64_t seed, BackendConfig* b) {
  std::seed_seq mix{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(c.what),
                    static_cast<std::uint32_t>(std::llround(c.size * 1e6))};
  std::mt19937_64 draw(mix);
  std::normal_distribution<double> normal;
  std::array<double, 3> v{normal(draw), normal(draw), normal(draw)};
  const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  for (double& x : v) x *= c.size / norm;
  b->sim_psd_moved_mm = b->sim_psd_turned_deg = b->sim_laser_moved_mm =
      b->sim_laser_turned_deg = {0, 0, 0};
  switch (c.what) {
    case Mounted::kNone:
      break;
    case Mounted::kPsdMoved:
      b->sim_psd_moved_mm = v;
      break;
    case Mounted::kPsdTurned:
      b->sim_psd_turned_deg = v;
      break;
    case Mounted::kLaserMoved:
      b->sim_laser_moved_mm = v;
      break;
    case Mounted::kLaserTurned:
      b->sim_laser_turned_deg = v;
      break;
  }
}

// Whether the verdict says the PSD is not where the reference had it (zerocal/calib/change.cpp's
// two reasons).
bool toldMoved(const Verdict& verdict) {
  return std::any_of(verdict.reasons.begin(), verdict.reasons.end(), [](const std::string& r) {
    return r.find("the PSD has moved since the reference") != std::string::npos ||
           r.find("the PSD's centre is") != std::string::npos;
  });
}

}  // namespace

void addRemountExperiment(CLI::App& experiment, RemountExperimentArgs& args) {
  CLI::App* cmd = args.cmd = experiment.add_subcommand(
      "remount",
      "how far the PSD or the laser may be re-mounted between a reference and a restore: per "
      "seeded world a reference, then a restore with one zero moved by 0.05..1 deg for each "
      "re-mount size (the PSD moved or turned on its base, the laser moved or turned on the "
      "flange, in a drawn direction), both sessions as warm; per size the restores' error, how "
      "many are usable, how many say the PSD moved; exit 0 when no restore offered a value beyond "
      "3 sigma as usable, else 7");
  addSeededWorldOptions(cmd, args.worlds, args.seed0, args.overrides, args.json, args.ideal_world);
  cmd->add_option("--psd-moved-mm", args.psd_moved_mm,
                  "sizes the PSD is moved by on its base (mm, comma-separated)")
      ->delimiter(',')
      ->default_str("0.005,0.01,0.02,0.05,0.1,0.5,1");
  cmd->add_option("--psd-turned-deg", args.psd_turned_deg,
                  "angles the PSD is turned by about its centre (deg)")
      ->delimiter(',')
      ->default_str("0.1,0.5,2");
  cmd->add_option("--laser-moved-mm", args.laser_moved_mm,
                  "sizes the laser is moved by on the flange (mm)")
      ->delimiter(',')
      ->default_str("0.02,0.1,0.5");
  cmd->add_option("--laser-turned-deg", args.laser_turned_deg,
                  "angles the laser's beam is turned by (deg)")
      ->delimiter(',')
      ->default_str("0.002,0.01,0.05,0.2");
  cmd->add_option("--warm-s", args.warm_s,
                  "the arm's warm-up at the reference and at each restore (backend.sim_warm_s, s)")
      ->default_val(args.warm_s);
}

int runRemountExperiment(const RemountExperimentArgs& args) {
  const DaemonConfig config = configOf(args);
  const std::vector<RemountCase> cases = casesOf(args);
  const ExperimentDir dir("zerocal-remount");
  std::vector<CaseFigures> figures(cases.size());
  Json worlds = Json::array();
  int failed = 0;  // sessions that did not complete

  for (int w = 0; w < args.worlds; ++w) {
    const std::uint64_t seed = args.seed0 + static_cast<std::uint64_t>(w);
    DaemonConfig base = config;
    base.backend.kind = BackendKind::kSim;
    base.backend.sim_seed = seed;
    base.backend.sim_warm_s = args.warm_s;
    base.session.data_dir = dir.path() + "/" + std::to_string(seed);
    // The motor replaced, as `experiment life` draws it.
    std::mt19937_64 draw(seed ^ 0x726573746f7265ull);  // "restore"
    const int joint = std::uniform_int_distribution<int>(2, 5)(draw);
    const double deg =
        std::uniform_real_distribution<double>(args.restore_min_deg, args.restore_max_deg)(draw) *
        (std::bernoulli_distribution(0.5)(draw) ? 1 : -1);
    Json row{{"seed", seed}, {"joint", joint}, {"change_deg", deg}};
    const ExperimentSession reference = runExperimentSession(base, SessionKind::kReference, false);
    if (!reference.completed) {
      ++failed;
      row["message"] = reference.message;
      if (!args.json)
        std::printf("world %llu: %s\n", static_cast<unsigned long long>(seed),
                    reference.message.c_str());
      worlds.push_back(row);
      continue;
    }
    Json restores = Json::array();
    for (std::size_t i = 0; i < cases.size(); ++i) {
      DaemonConfig c = base;
      c.backend.sim_zero_change_joint = joint;
      c.backend.sim_zero_change_deg = deg;
      setRemount(cases[i], seed, &c.backend);
      const ExperimentSession restore = runExperimentSession(c, SessionKind::kRestore, false);
      Json one{{"remount", caseName(cases[i].what)},
               {"size", cases[i].size},
               {"unit", unitOf(cases[i].what)}};
      if (!restore.completed) {
        ++failed;
        one["message"] = restore.message;
        restores.push_back(one);
        continue;
      }
      CaseFigures& f = figures[i];
      const SolveReport& r = restore.result.report;
      const std::array<double, kOffsetCount> truth =
          offsetDifference(restore.result.truth->offsets_deg, reference.result.truth->offsets_deg);
      ++f.restores;
      f.usable += r.verdict.usable;
      f.told_moved += toldMoved(r.verdict);
      bool wrong = false;
      Json errors = Json::array();
      for (int k = 0; k < kOffsetCount; ++k) {
        const ParameterEstimate& e = r.parameters[k];
        if (!std::isfinite(e.value) || !(e.sigma > 0) || !std::isfinite(e.sigma)) {
          errors.push_back(nullptr);
          continue;
        }
        const double error = e.value - truth[k];
        const double sigmas = std::abs(error) / e.sigma;
        ++f.estimates;
        f.covered += e.ci95_low <= truth[k] && truth[k] <= e.ci95_high;
        f.sq += error * error;
        f.beyond += sigmas > args.max_sigmas;
        f.worst_sigmas = std::max(f.worst_sigmas, sigmas);
        wrong = wrong || sigmas > args.max_sigmas;
        if (r.verdict.usable) {
          ++f.usable_estimates;
          f.usable_sq += error * error;
        }
        errors.push_back({{"error_deg", error}, {"sigma_deg", e.sigma}});
      }
      f.wrong_usable += r.verdict.usable && wrong;
      one["usable"] = r.verdict.usable;
      one["reasons"] = r.verdict.reasons;
      one["offsets"] = errors;
      one["cell_time_s"] = restore.cell_time_s;
      restores.push_back(one);
    }
    row["restores"] = restores;
    worlds.push_back(row);
  }

  const auto rms = [](double sq, int n) { return n > 0 ? std::sqrt(sq / n) : 0.0; };
  bool pass = failed == 0;
  // The tolerance of each kind of re-mount: the largest size up to which (from the smallest on)
  // every size keeps the restore's figures: RMS error, usable share, and 95% intervals covering
  // at least min_coverage (below 95% by two binomial standard deviations of 80 intervals, so
  // that chance alone does not end it; a single offset beyond 3 sigma in 80 is chance too, and
  // is judged by the exit code, not here).
  Json summary = Json::array();
  std::array<double, 5> tolerance{};
  std::array<bool, 5> broken{};
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const CaseFigures& f = figures[i];
    pass = pass && f.wrong_usable == 0;
    const double share = f.restores > 0 ? static_cast<double>(f.usable) / f.restores : 0.0;
    const double coverage = f.estimates > 0 ? static_cast<double>(f.covered) / f.estimates : 0.0;
    const bool keeps = f.restores > 0 && rms(f.sq, f.estimates) <= args.max_rms_deg &&
                       share >= args.min_usable_share && coverage >= args.min_coverage;
    const auto what = static_cast<std::size_t>(cases[i].what);
    if (!keeps) broken[what] = true;
    if (keeps && !broken[what]) tolerance[what] = cases[i].size;
    summary.push_back({{"remount", caseName(cases[i].what)},
                       {"size", cases[i].size},
                       {"unit", unitOf(cases[i].what)},
                       {"restores", f.restores},
                       {"usable", f.usable},
                       {"told_psd_moved", f.told_moved},
                       {"rms_error_deg", rms(f.sq, f.estimates)},
                       {"beyond_max_sigmas", f.beyond},
                       {"estimates", f.estimates},
                       {"worst_error_sigmas", f.worst_sigmas},
                       {"coverage_95", coverage},
                       {"rms_error_usable_deg", rms(f.usable_sq, f.usable_estimates)},
                       {"wrong_usable", f.wrong_usable},
                       {"keeps_figures", keeps}});
  }
  Json tolerances = Json::object();
  for (const Mounted m :
       {Mounted::kPsdMoved, Mounted::kPsdTurned, Mounted::kLaserMoved, Mounted::kLaserTurned})
    tolerances[caseName(m)] = tolerance[static_cast<std::size_t>(m)];

  if (args.json) {
    std::cout << Json{{"worlds", worlds},
                      {"seed0", args.seed0},
                      {"world", config.backend.sim_ideal_world ? "ideal" : "realistic"},
                      {"warm_s", args.warm_s},
                      {"failed_sessions", failed},
                      {"cases", summary},
                      {"tolerance", tolerances},
                      {"requirements",
                       {{"max_error_sigmas", args.max_sigmas},
                        {"max_rms_deg", args.max_rms_deg},
                        {"min_coverage_95", args.min_coverage},
                        {"min_usable_share", args.min_usable_share}}},
                      {"pass", pass}}
                     .dump(2)
              << "\n";
    return pass ? 0 : kRequirementNotMet;
  }
  std::printf(
      "%d worlds from seed %llu (%s), a reference and one restore per re-mount each, the arm "
      "warm for %.0f s at both; %d sessions did not complete\n\n",
      args.worlds, static_cast<unsigned long long>(args.seed0),
      config.backend.sim_ideal_world ? "ideal" : "realistic", args.warm_s, failed);
  std::printf("%-13s %7s %-4s %8s %11s %12s %9s %14s %12s %14s\n", "re-mount", "size", "", "usable",
              "told moved", "RMS err deg", "cover 95", "beyond 3 sig", "worst sigmas",
              "wrong usable");
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const CaseFigures& f = figures[i];
    std::printf("%-13s %7.3f %-4s %3d of %-2d %11d %12.5f %8.1f%% %7d of %-3d %12.2f %14d\n",
                caseName(cases[i].what).c_str(), cases[i].size, unitOf(cases[i].what), f.usable,
                f.restores, f.told_moved, rms(f.sq, f.estimates),
                f.estimates > 0 ? 100.0 * f.covered / f.estimates : 0.0, f.beyond, f.estimates,
                f.worst_sigmas, f.wrong_usable);
  }
  std::printf(
      "\ntolerance (the largest size keeping RMS <= %.3f deg, >= %.0f%% usable, >= %.0f%% "
      "of the 95%% intervals covering):",
      args.max_rms_deg, 100 * args.min_usable_share, 100 * args.min_coverage);
  for (const auto& t : tolerances.items())
    std::printf(" %s %.3f %s;", t.key().c_str(), t.value().get<double>(),
                t.key().find("turned") != std::string::npos ? "deg" : "mm");
  std::printf("\nno restore offered a value beyond %.1f sigma as usable  %s\n", args.max_sigmas,
              pass ? "ok" : "FAIL");
  return pass ? 0 : kRequirementNotMet;
}

}  // namespace zerocal::lab
