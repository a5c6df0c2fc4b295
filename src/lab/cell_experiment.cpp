#include "cell_experiment.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "experiment_sessions.h"
#include "zerocal/calib/solver.h"
#include "zerocal/error.h"
#include "zerocal/io/durable_file.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/sim/world.h"
#include "zerocal/store/journal.h"

namespace zerocal::lab {
namespace {

using Json = nlohmann::json;

DaemonConfig configOf(const CellExperimentArgs& args) {
  DaemonConfig config;
  ConfigOrigins origins;
  std::vector<std::string> problems;
  if (args.ideal_world)
    applyConfigOverride(config, "backend.sim_ideal_world=true", origins, problems);
  for (const std::string& o : args.overrides) applyConfigOverride(config, o, origins, problems);
  for (const std::string& p : validateDaemonConfig(config, origins)) problems.push_back(p);
  if (!problems.empty()) throw ConfigError("zerocal-lab experiment cell", problems);
  return config;
}

struct Calibration {
  bool completed = false;
  service::SessionState state = service::SessionState::kIdle;
  std::string message;  // why not completed
  ResultFile result;    // when completed
  double cell_time_s = 0;
  std::vector<Pose> plan;
  Prediction prediction;            // the plan's, before any move
  std::vector<PoseRecord> records;  // the journal's, when completed
};

// One calibration exactly as zerocald runs one: the daemon's own parts, from the same
// configuration (the backend, the session manager with its run settings and recovery hooks, its
// plan, journal, solve and result).
Calibration calibrate(const DaemonConfig& config) {
  service::ManagerSettings settings = service::managerSettingsOf(config);
  settings.write_reports = nullptr;       // figures only
  settings.unattended_placements = true;  // --set session.placements=N: the cell moves its PSD
  const std::unique_ptr<CellBackend> backend = service::makeBackend(config);
  service::SessionManager manager(*backend, settings);
  Calibration out;
  try {
    // What a calibration gives is measured whatever its plan predicts: asked for explicitly.
    service::StartRequest request = manager.defaultRequest();
    request.even_if_not_usable = true;
    const Plan plan = manager.preview(request);
    out.plan = plan.poses;
    out.prediction = plan.prediction;
    manager.start(request);
  } catch (const service::Refused& e) {
    out.message = e.what();
  }
  const service::SessionStatus end = manager.waitIdle();
  out.state = end.state;
  out.completed = out.message.empty() && end.state == service::SessionState::kDone;
  if (out.message.empty()) out.message = end.message;
  if (out.completed) {
    out.result = manager.result(end.session_id);
    out.records =
        readJournal(config.session.data_dir + "/" + end.session_id + "/journal.jsonl").records;
  }
  out.cell_time_s = end.cell_time_s;
  return out;
}

DaemonConfig worldConfig(const DaemonConfig& config, std::uint64_t seed, const std::string& dir) {
  DaemonConfig c = config;
  c.backend.kind = BackendKind::kSim;
  c.backend.sim_seed = seed;
  c.session.data_dir = dir + "/" + std::to_string(seed);
  return c;
}

// Each world twice: without gross errors, and with one at a plan pose; the second must name the
// pose, measure it again, and end where the first did. Both run on the seed's realistic world
// written as a world file, its gross-error rates zero, the second with the one error added.
int runGrossErrorExperiment(const CellExperimentArgs& args) {
  if (args.ideal_world)
    throw ConfigError("zerocal-lab experiment cell",
                      {"--gross-error: the ideal world has no gross errors"});
  const DaemonConfig config = configOf(args);
  if (!config.backend.sim_world.empty())
    throw ConfigError("zerocal-lab experiment cell",
                      {"--gross-error: runs the seeds' worlds, not backend.sim_world"});
  const ExperimentDir dir("zerocal-cell");
  Json worlds = Json::array();
  int runs = 0, failed = 0, named = 0, other_named = 0;
  double worst_change = 0, worst_change_stat = 0;
  if (!args.json)
    std::printf("%6s %5s %12s %6s %9s  %s\n", "seed", "pose", "kind", "named", "measured",
                "change of delta2 .. delta5 in reported sigmas (statistical sigmas)");
  for (int w = 0; w < args.worlds; ++w) {
    const std::uint64_t seed = args.seed0 + static_cast<std::uint64_t>(w);
    World world = randomWorld(seed);
    world.gross.stray_light_rate = world.gross.unsettled_rate = 0;
    const auto runOn = [&](const World& on, const std::string& name) {
      const std::string file = dir.path() + "/" + name + "-" + std::to_string(seed) + ".yaml";
      writeFileDurably(file, worldYaml(on));
      DaemonConfig c = worldConfig(config, seed, dir.path() + "/" + name);
      c.backend.sim_seed.reset();
      c.backend.sim_world = file;
      return calibrate(c);
    };
    const Calibration clean = runOn(world, "clean");
    const int pose = 1 + static_cast<int>(seed % std::max<std::size_t>(1, clean.plan.size()));
    world.gross.forced_kind =
        seed % 2 == 1 ? GrossErrors::Kind::kStrayLight : GrossErrors::Kind::kUnsettled;
    const std::string kind = grossKindName(world.gross.forced_kind);
    Json row{{"seed", seed}, {"pose", pose}, {"kind", kind}};
    ++runs;
    // A pair that did not complete: the reason, and no comparison.
    const auto incomplete = [&](const std::string& message) {
      ++failed;
      row["message"] = message;
      if (!args.json)
        std::printf("%6llu %5d %12s  %s\n", static_cast<unsigned long long>(seed), pose,
                    kind.c_str(), message.c_str());
      worlds.push_back(row);
    };
    if (!clean.completed) {
      incomplete("without the gross error: " + clean.message);
      continue;
    }
    // Where the clean session recorded the pose: the gross one comes to rest there too, its
    // moves the same until then (the planned joints once the spot is aimed at are not).
    world.gross.forced_at_deg = clean.records[pose - 1].joints_deg;
    const Calibration gross = runOn(world, "gross");
    if (!gross.completed) {
      incomplete("with the gross error: " + gross.message);
      continue;
    }
    // Named: the daemon measured the pose again because the first solve named it, or (a pose at
    // an earlier PSD placement, which cannot be measured again) the result leaves it out.
    const std::vector<int> again = gross.result.remeasured.value_or(std::vector<int>{});
    const std::vector<PoseResidual>& fitted = gross.result.report.poses;
    const bool left_out = pose <= static_cast<int>(fitted.size()) && fitted[pose - 1].outlier;
    const bool found = left_out || std::find(again.begin(), again.end(), pose) != again.end();
    named += found;
    other_named += !found && !again.empty();
    std::string line;
    Json changes = Json::array();
    for (int k = 0; k < kOffsetCount; ++k) {
      const ParameterEstimate& c = clean.result.report.parameters[k];
      const ParameterEstimate& g = gross.result.report.parameters[k];
      if (!std::isfinite(c.value) || !std::isfinite(g.value) || !(g.sigma > 0)) {
        line += "      n/a     ";
        continue;
      }
      // The statistical part alone: the link tolerances' part is the same in both sessions.
      const double stat =
          std::sqrt(std::max(0.0, g.sigma * g.sigma - g.model_sigma * g.model_sigma));
      const double change = std::abs(g.value - c.value);
      worst_change = std::max(worst_change, change / g.sigma);
      if (stat > 0) worst_change_stat = std::max(worst_change_stat, change / stat);
      changes.push_back({{"name", unknownName(k)},
                         {"clean_deg", c.value},
                         {"remeasured_deg", g.value},
                         {"sigma_deg", g.sigma},
                         {"statistical_sigma_deg", stat},
                         {"change_sigmas", change / g.sigma}});
      line += fmt::format(FMT_STRING(" {:5.2f} ({:5.2f})"), change / g.sigma,
                          stat > 0 ? change / stat : 0.0);
    }
    row["remeasured"] = again;
    row["named"] = found;
    row["offsets"] = changes;
    if (!args.json) {
      std::string measured;
      for (const int p : again) measured += (measured.empty() ? "" : ",") + std::to_string(p);
      std::printf("%6llu %5d %12s %6s %9s %s\n", static_cast<unsigned long long>(seed), pose,
                  kind.c_str(), found ? "yes" : "no", measured.empty() ? "-" : measured.c_str(),
                  line.c_str());
    }
    worlds.push_back(row);
  }
  const double share = runs > 0 ? static_cast<double>(named) / runs : 0.0;
  const bool pass =
      failed == 0 && share >= args.min_named_share && worst_change <= args.max_change_sigmas;
  if (args.json) {
    std::cout << Json{{"worlds", worlds},
                      {"seed0", args.seed0},
                      {"failed_runs", failed},
                      {"named_share", share},
                      {"other_pose_named", other_named},
                      {"worst_change_sigmas", worst_change},
                      {"worst_change_statistical_sigmas", worst_change_stat},
                      {"requirements",
                       {{"min_named_share", args.min_named_share},
                        {"max_change_sigmas", args.max_change_sigmas}}},
                      {"pass", pass}}
                     .dump(2)
              << "\n";
  } else {
    std::printf("\n%d worlds from seed %llu, one gross error each; %d pair(s) did not complete\n",
                runs, static_cast<unsigned long long>(args.seed0), failed);
    std::printf(
        "named          %d of %d (%.1f%%, >= %.0f%%) %s; another pose measured again in %d\n",
        named, runs, 100 * share, 100 * args.min_named_share,
        share >= args.min_named_share ? "ok" : "FAIL", other_named);
    std::printf("worst change   %.2f reported sigma (<= %.1f) %s; %.2f statistical sigma\n",
                worst_change, args.max_change_sigmas,
                worst_change <= args.max_change_sigmas ? "ok" : "FAIL", worst_change_stat);
  }
  return pass ? 0 : kRequirementNotMet;
}

}  // namespace

CLI::App* addCellExperiment(CLI::App& experiment, CellExperimentArgs& args) {
  CLI::App* cmd = experiment.add_subcommand(
      "cell",
      "whole calibrations on the simulated cell (real client and driver), one per seeded world, "
      "with the daemon's default settings; exit 0 when every estimate of delta2..delta5 is within "
      "3 sigma of the truth, their RMS error <= 0.005 deg and every calibration within the cell "
      "time and move requirements below, else 7");
  cmd->add_option("--worlds", args.worlds, "number of seeded worlds")
      ->default_val(args.worlds)
      ->check(CLI::Range(1, 10000));
  cmd->add_option("--seed0", args.seed0, "seed of the first world (then seed0+1, ...)")
      ->default_val(args.seed0);
  cmd->add_option("--set", args.overrides,
                  "override one daemon configuration key: section.key=value (repeatable)");
  cmd->add_option("--max-cell-time", args.max_cell_time_s,
                  "requirement: cell seconds of every calibration")
      ->default_val(args.max_cell_time_s)
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-moves", args.max_moves,
                  "requirement: controller moves of every calibration (planned ones included)")
      ->default_val(args.max_moves)
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-pose-moves", args.max_pose_moves,
                  "requirement: controller moves at any one pose (its planned move included)")
      ->default_val(args.max_pose_moves)
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--json", args.json, "print one JSON object instead of text");
  cmd->add_flag("--gross-error", args.gross_error,
                "run each world twice, without gross errors and with exactly one (stray light or "
                "an unsettled reading, alternately) at one plan pose; exit 0 when the pose is "
                "named and measured again in at least 95% of the worlds and every estimate of "
                "delta2..delta5 is within 1 reported sigma of the clean session's, else 7");
  cmd->add_flag("--calibrated-model", args.calibrated_model,
                "first calibrate each world at 3 PSD placements x 12 poses, as a technician "
                "would once: the calibration measured then plans and solves with the calibrated "
                "model that wrote (model.yaml), as zerocald does");
  cmd->add_flag("--ideal-world", args.ideal_world,
                "the seeds' ideal worlds (exact arm, PSD orientation known, no gross errors) "
                "instead of the realistic ones (docs/simulated-cell.md)");
  return cmd;
}

int runCellExperiment(const CellExperimentArgs& args) {
  if (args.gross_error) return runGrossErrorExperiment(args);
  const DaemonConfig config = configOf(args);
  if (args.calibrated_model && config.session.placements > 1)
    throw ConfigError("zerocal-lab experiment cell",
                      {"--calibrated-model: the calibration measured with the model is at one "
                       "placement (session.placements is " +
                       std::to_string(config.session.placements) + ")"});
  int models_written = 0, with_model = 0;  // --calibrated-model: models written, and used
  const ExperimentDir dir("zerocal-cell");
  Json worlds = Json::array();
  double sum_sq = 0, worst_sigmas = 0, max_cell_s = 0;
  int estimates = 0, failed_runs = 0, covered = 0;  // covered: truth inside value +- 1.96 sigma
  // Results whose verdict refuses them, and offsets a result withholds (not determined): the
  // worst error is judged on usable results only, as a technician would use them.
  int refused_results = 0, withheld = 0;
  // Whether the reported sigmas are as large as the errors, offset by offset: every offset with a
  // value and a sigma, withheld ones included (their sigma is what says they are not good enough).
  struct OffsetSums {
    double normalised_sq = 0;
    int count = 0, covered = 0;
  };
  std::array<OffsetSums, kOffsetCount> per_offset{};
  int noise_gated = 0;  // results the noise gate refuses (the poses miss beyond the noise model)
  // The plans' predicted total sigma of delta2 (deg), the least determined offset at one placement.
  double delta2_predicted_min = INFINITY, delta2_predicted_max = 0;
  // Per pose over the worlds: sums for the mean breakdown, maxima of the moves.
  struct PoseSums {
    double move_s = 0, acquisition_s = 0, servo_s = 0, settle_s = 0, overhead_s = 0,
           fine_point_s = 0;
    int moves_max = 0, search_moves_max = 0, count = 0;
    long moves = 0;
  };
  std::vector<PoseSums> per_pose;
  int most_moves = 0, most_pose_moves = 0;
  if (!args.json)
    std::printf("%6s %9s %7s %6s  %s\n", "seed", "state", "cell_s", "moves",
                "error deg (sigmas) of delta2 .. delta5");

  for (int w = 0; w < args.worlds; ++w) {
    const std::uint64_t seed = args.seed0 + static_cast<std::uint64_t>(w);
    const DaemonConfig world_config = worldConfig(config, seed, dir.path());
    std::string model_note;
    if (args.calibrated_model) {
      DaemonConfig first = world_config;
      first.session.placements = args.model_placements;
      first.session.poses = args.model_poses;
      const Calibration model = calibrate(first);
      const bool written = model.completed && !model.result.model_file.empty();
      models_written += written ? 1 : 0;
      model_note = written ? "" : " (no model: " + model.message + ")";
    }
    const Calibration run = calibrate(world_config);
    const bool completed = run.completed;
    const std::string& message = run.message;
    const ResultFile& result = run.result;
    const Json result_json = toJson(result);
    const double cell_time_s = run.cell_time_s;

    Json world{{"seed", seed}, {"cell_time_s", cell_time_s}};
    if (args.calibrated_model) {
      world["model_from"] = completed ? result.model_from : "";
      with_model += completed && !result.model_from.empty() ? 1 : 0;
    }
    Json predicted = Json::array();
    for (int k = 0; k < kOffsetCount && k < static_cast<int>(run.prediction.sigma.size()); ++k)
      predicted.push_back(run.prediction.sigma[k]);
    world["predicted_sigma_deg"] = predicted;
    if (!run.prediction.sigma.empty()) {
      delta2_predicted_min = std::min(delta2_predicted_min, run.prediction.sigma[0]);
      delta2_predicted_max = std::max(delta2_predicted_max, run.prediction.sigma[0]);
    }
    world["state"] = completed ? "completed" : service::stateName(run.state);
    if (!completed) {
      ++failed_runs;
      world["message"] = message;
    }
    max_cell_s = std::max(max_cell_s, cell_time_s);
    int moves = 0;
    if (completed) {
      for (const PoseTimes& pose : result.pose_breakdown.value_or(std::vector<PoseTimes>{})) {
        if (!pose.skipped.empty()) continue;  // never measured: no moves to count
        const int i = pose.pose - 1;
        // Every move the controller made for the pose: the planned one and the servo's.
        const int pose_moves = pose.servo.moves + 1;
        moves += pose_moves;
        most_pose_moves = std::max(most_pose_moves, pose_moves);
        if (per_pose.size() <= static_cast<std::size_t>(i)) per_pose.resize(i + 1);
        PoseSums& p = per_pose[i];
        p.move_s += pose.servo.move_s;
        p.acquisition_s += pose.servo.acquisition_s;
        p.servo_s += pose.servo.servo_s;
        p.settle_s += pose.servo.settle_s;
        p.overhead_s += pose.move_overhead_s.value_or(0.0);
        p.fine_point_s += pose.fine_point_settle_s.value_or(0.0);
        p.moves += pose_moves;
        p.moves_max = std::max(p.moves_max, pose_moves);
        p.search_moves_max = std::max(p.search_moves_max, pose.servo.search_moves);
        ++p.count;
      }
      world["poses"] = result_json["pose_breakdown"];
      world["recoveries"] = result_json["recoveries"];
    }
    world["moves"] = moves;
    most_moves = std::max(most_moves, moves);
    std::string line;
    if (completed) {
      Json offsets = Json::array();
      const bool usable = !result.verdict_recorded || result.report.verdict.usable;
      if (!usable) ++refused_results;
      if (result.report.noise_scale > SolveOptions{}.max_noise_scale) ++noise_gated;
      world["usable"] = usable;
      if (!usable) world["not_usable_because"] = result.report.verdict.reasons;
      world["noise_scale"] = result.report.noise_scale;
      for (int k = 0; k < kOffsetCount; ++k) {
        const std::string name = unknownName(k);
        const ParameterEstimate& e = result.report.parameters[k];
        if (std::isfinite(e.value) && e.sigma > 0 && std::isfinite(e.sigma)) {
          const double z = (e.value - result.truth->offsets_deg[k]) / e.sigma;
          per_offset[k].normalised_sq += z * z;
          ++per_offset[k].count;
          if (std::abs(z) <= 1.959964) ++per_offset[k].covered;
        }
        if (!e.identifiable || !std::isfinite(e.value) || !std::isfinite(e.sigma)) {
          ++withheld;
          line += "   withheld       ";
          continue;
        }
        const double truth = result.truth->offsets_deg[k];
        const double value = e.value, sigma = e.sigma;
        const double error = value - truth;
        const double sigmas = std::abs(error) / sigma;
        sum_sq += error * error;
        if (usable) worst_sigmas = std::max(worst_sigmas, sigmas);
        ++estimates;
        if (sigmas <= 1.959964) ++covered;
        offsets.push_back({{"name", name},
                           {"value_deg", value},
                           {"truth_deg", truth},
                           {"error_deg", error},
                           {"sigma_deg", sigma},
                           {"model_sigma_deg", e.model_sigma},
                           {"error_sigmas", sigmas}});
        line += fmt::format(FMT_STRING(" {:+.5f} ({:.2f})"), error, sigmas);
      }
      world["offsets"] = offsets;
      world["chi2_per_dof"] = result_json["chi2_per_dof"];
    } else {
      line = " " + message;
    }
    line += model_note;
    if (!args.json)
      std::printf("%6llu %9s %7.1f %6d %s\n", static_cast<unsigned long long>(seed),
                  world["state"].get<std::string>().c_str(), cell_time_s, moves, line.c_str());
    worlds.push_back(world);
  }

  const double rms = estimates > 0 ? std::sqrt(sum_sq / estimates) : 0.0;
  const double coverage = estimates > 0 ? static_cast<double>(covered) / estimates : 0.0;
  const bool sigmas_ok = failed_runs == 0 && worst_sigmas <= args.max_sigmas;
  const bool rms_ok = failed_runs == 0 && rms <= args.max_rms_deg;
  const bool time_ok = failed_runs == 0 && max_cell_s <= args.max_cell_time_s;
  const bool moves_ok =
      failed_runs == 0 && most_moves <= args.max_moves && most_pose_moves <= args.max_pose_moves;
  const bool pass = sigmas_ok && rms_ok && time_ok && moves_ok;

  Json normalised = Json::array();
  for (int k = 0; k < kOffsetCount; ++k) {
    const OffsetSums& o = per_offset[k];
    const double n = std::max(1, o.count);
    normalised.push_back({{"name", unknownName(k)},
                          {"count", o.count},
                          {"rms_normalised_error", std::sqrt(o.normalised_sq / n)},
                          {"coverage_95", o.covered / n}});
  }

  Json breakdown = Json::array();
  for (std::size_t i = 0; i < per_pose.size(); ++i) {
    const PoseSums& p = per_pose[i];
    const double n = std::max(1, p.count);
    breakdown.push_back({{"pose", i + 1},
                         {"mean_move_s", p.move_s / n},
                         {"mean_acquisition_s", p.acquisition_s / n},
                         {"mean_servo_s", p.servo_s / n},
                         {"mean_settle_s", p.settle_s / n},
                         {"mean_move_overhead_s", p.overhead_s / n},
                         {"mean_fine_point_settle_s", p.fine_point_s / n},
                         {"mean_moves", p.moves / n},
                         {"max_moves", p.moves_max},
                         {"max_search_moves", p.search_moves_max}});
  }
  if (args.json) {
    std::cout << Json{{"worlds", worlds},
                      {"seed0", args.seed0},
                      {"pose_breakdown", breakdown},
                      {"failed_runs", failed_runs},
                      {"rms_error_deg", rms},
                      {"worst_error_sigmas", worst_sigmas},
                      {"coverage_95", coverage},
                      {"refused_results", refused_results},
                      {"withheld_offsets", withheld},
                      {"noise_gated_results", noise_gated},
                      {"delta2_predicted_sigma_deg", {delta2_predicted_min, delta2_predicted_max}},
                      {"per_offset", normalised},
                      {"world", args.ideal_world ? "ideal" : "realistic"},
                      {"calibrated_model", args.calibrated_model
                                               ? Json{{"placements", args.model_placements},
                                                      {"poses", args.model_poses},
                                                      {"models_written", models_written},
                                                      {"calibrations_with_a_model", with_model}}
                                               : Json(nullptr)},
                      {"max_cell_time_s", max_cell_s},
                      {"max_moves", most_moves},
                      {"max_pose_moves", most_pose_moves},
                      {"requirements",
                       {{"max_error_sigmas", args.max_sigmas},
                        {"max_rms_error_deg", args.max_rms_deg},
                        {"max_cell_time_s", args.max_cell_time_s},
                        {"max_moves", args.max_moves},
                        {"max_pose_moves", args.max_pose_moves}}},
                      {"pass", pass}}
                     .dump(2)
              << "\n";
  } else {
    std::printf(
        "\nper pose, mean over the worlds (cell seconds; overhead and fine_pt are the "
        "controller's\nper-move costs within move, acquisition and servo) and moves (the "
        "planned one included)\n");
    std::printf("%5s %7s %13s %8s %9s %9s %8s %11s %10s %11s\n", "pose", "move_s", "acquisition_s",
                "servo_s", "settle_s", "overhead", "fine_pt", "mean_moves", "max_moves",
                "max_search");
    for (const Json& b : breakdown)
      std::printf("%5d %7.2f %13.2f %8.2f %9.2f %9.2f %8.2f %11.1f %10d %11d\n",
                  b["pose"].get<int>(), b["mean_move_s"].get<double>(),
                  b["mean_acquisition_s"].get<double>(), b["mean_servo_s"].get<double>(),
                  b["mean_settle_s"].get<double>(), b["mean_move_overhead_s"].get<double>(),
                  b["mean_fine_point_settle_s"].get<double>(), b["mean_moves"].get<double>(),
                  b["max_moves"].get<int>(), b["max_search_moves"].get<int>());
    std::printf("\n%d worlds from seed %llu, %d did not complete\n", args.worlds,
                static_cast<unsigned long long>(args.seed0), failed_runs);
    std::printf("world          %s\n", args.ideal_world ? "ideal" : "realistic");
    if (args.calibrated_model)
      std::printf(
          "model          %d of %d worlds' calibrations at %d placements x %d poses wrote "
          "a calibrated model; %d calibrations used one\n",
          models_written, args.worlds, args.model_placements, args.model_poses, with_model);
    std::printf("95%% coverage   %.1f%% of %d offsets inside value +- 1.96 sigma\n", 100 * coverage,
                estimates);
    std::printf("refused        %d results not usable by their verdict, %d offsets withheld\n",
                refused_results, withheld);
    std::printf("noise gate     %d results refused for missing beyond the noise model\n",
                noise_gated);
    std::printf("predicted      delta2's sigma before any move %.4f..%.4f deg over the plans\n",
                delta2_predicted_min, delta2_predicted_max);
    std::printf("per offset     RMS error/sigma and 95%% coverage, withheld offsets included:\n");
    for (const Json& o : normalised)
      std::printf("               %s  %.2f  %5.1f%%  (%d)\n", o["name"].get<std::string>().c_str(),
                  o["rms_normalised_error"].get<double>(), 100 * o["coverage_95"].get<double>(),
                  o["count"].get<int>());
    std::printf("worst error    %.2f sigma   (<= %.1f)  %s  (usable results)\n", worst_sigmas,
                args.max_sigmas, sigmas_ok ? "ok" : "FAIL");
    std::printf("RMS error      %.5f deg (<= %.3f) %s\n", rms, args.max_rms_deg,
                rms_ok ? "ok" : "FAIL");
    std::printf("max cell time  %.1f s      (<= %.0f)   %s\n", max_cell_s, args.max_cell_time_s,
                time_ok ? "ok" : "FAIL");
    std::printf("max moves      %d, %d at one pose (<= %d, %d) %s\n", most_moves, most_pose_moves,
                args.max_moves, args.max_pose_moves, moves_ok ? "ok" : "FAIL");
  }
  return pass ? 0 : kRequirementNotMet;
}

}  // namespace zerocal::lab
