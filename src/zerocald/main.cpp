// zerocald: the cell daemon. This version runs one calibration and exits (--once), on the
// simulated cell (--sim, or backend.kind: sim); the long-running service with its control port,
// and the hardware backend, are not built yet and are refused with a message saying so.
// Exit codes: 0 calibrated; 1 unexpected failure; 2 bad configuration or usage; 3 the session
// faulted or aborted (the journal keeps every recorded pose); 4 the plan cannot identify
// delta2..delta5.
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <iostream>

#include "report_format.h"
#include "zerocal/calib/planner.h"
#include "zerocal/daemon/config.h"
#include "zerocal/daemon/journal.h"
#include "zerocal/daemon/logging.h"
#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/session/calibration_run.h"
#include "zerocal/sim/simulated_rig.h"

namespace zerocal {
namespace {

enum ExitCode { kOk = 0, kFailure = 1, kBadInput = 2, kStopped = 3, kNotIdentifiable = 4 };

std::atomic<bool> g_abort{false};
extern "C" void onSignal(int) { g_abort = true; }  // only an atomic store: async-signal-safe

Pattern patternOf(PlanKind kind) {
  switch (kind) {
    case PlanKind::kI:
      return Pattern::kI;
    case PlanKind::kII:
      return Pattern::kII;
    case PlanKind::kMixed:
      return Pattern::kMixed;
    default:
      return Pattern::kOptimal;
  }
}

servo::ServoOptions servoOptionsOf(const ServoConfig& c, double limit_margin_deg) {
  servo::ServoOptions o;
  o.mode = c.stop == ServoStop::kZone ? servo::ServoMode::kHitPoint : servo::ServoMode::kCentre;
  o.tolerance_mm = c.tolerance_um * 1e-3;
  o.max_step_deg = c.max_step_deg;
  o.max_iterations = c.max_iterations;
  o.max_time_s = c.timeout_s;
  o.search_radius_mm = c.search_radius_mm;
  o.search_step_mm = c.search_step_mm;
  o.max_search_time_s = c.search_time_s;
  o.limit_margin_deg = limit_margin_deg;
  return o;
}

int runOnce(const DaemonConfig& cfg, bool json) {
  auto log = makeLogger("session");
  if (cfg.backend.kind != BackendKind::kSim)
    throw ConfigError("zerocald", {"--once on the hardware backend is not built yet; use --sim "
                                   "(or backend.kind: sim)"});
  if (!cfg.backend.sim_host.empty())
    throw ConfigError("zerocald", {"an external zerocal-sim (backend.sim_host) is not supported "
                                   "by --once yet; leave it empty for the in-process cell"});
  if (cfg.session.plan == PlanKind::kFile)
    throw ConfigError("zerocald", {"session.plan: file is not supported by --once yet"});

  sim::SimulatedCellOptions cell_options;
  cell_options.world = cfg.backend.sim_world.empty() ? randomWorld(cfg.backend.sim_seed.value_or(1))
                                                     : loadWorld(cfg.backend.sim_world);
  const std::uint64_t seed = cfg.backend.sim_seed.value_or(1);
  cell_options.controller_seed = seed;
  cell_options.psd.seed = static_cast<std::uint32_t>(seed) + 100;
  // The controller section applies to the simulated controller as to a real one. Its
  // max_step_deg is not applied here: the moves between planned poses are large by design.
  sim::SimulatedRig rig(std::move(cell_options), [&](Irc5Options& o) {
    o.limit_margin_deg = cfg.controller.limit_margin_deg;
    o.speed_tcp_mm_s = cfg.controller.speed_tcp_mm_s;
    o.speed_ori_deg_s = cfg.controller.speed_ori_deg_s;
  });
  const World& world = rig.cell.world();

  const sim::SessionKnowledge given = sim::knowledgeOf(world);
  const CellModel& knowledge = given.cell;
  const Eigen::Vector3d& taught = given.taught_centre;

  PlanOptions plan_options;
  plan_options.pattern = patternOf(cfg.session.plan);
  plan_options.poses = cfg.session.poses;
  plan_options.noise_mm = cfg.session.noise_mm;
  plan_options.psd_normal = knowledge.psd_rotation.col(2);
  const Plan plan = planPoses(knowledge, taught, plan_options);
  std::cerr << toText(plan);
  for (int k = 0; k < kOffsetCount; ++k)
    if (!plan.prediction.identifiable[k]) {
      log->error("the plan cannot identify {}: refused before any move", unknownName(k));
      return kNotIdentifiable;
    }

  SessionStore store(cfg.session.data_dir);
  const SessionInfo session = store.create(toJson(plan), configToJson(cfg));
  log->info("session {} in {}", session.id, session.dir);
  Journal journal(store.journalPath(session.id));

  RunSettings settings;
  settings.servo = servoOptionsOf(cfg.servo, cfg.controller.limit_margin_deg);
  settings.solve.noise_mm = cfg.session.noise_mm;
  CalibrationRun run(knowledge, taught, plan.poses, settings, journal);
  const int n = static_cast<int>(plan.poses.size());
  run.on_pose = [&](const PoseRecord& r) {
    std::fprintf(stderr, "pose %d of %d recorded: %d servo moves, %.2f um from the aim point\n",
                 r.index + 1, n, r.servo.moves, r.servo.final_error_um);
  };
  const double start_s = rig.cell.nowS();
  const RunOutcome outcome = run.run(rig.client, rig.psd, rig.cell, g_abort);
  const double cell_time_s = rig.cell.nowS() - start_s;
  if (outcome.state != RunState::kCompleted) {
    log->error("session {} {}: {} ({} poses journalled in {})", session.id,
               outcome.state == RunState::kAborted ? "aborted" : "faulted", outcome.message,
               outcome.records.size(), store.journalPath(session.id));
    return kStopped;
  }

  nlohmann::json result = toJson(*outcome.report);
  result["session"] = session.id;
  result["cell_time_s"] = cell_time_s;
  result["truth"] = nlohmann::json::object();
  for (int k = 0; k < kOffsetCount; ++k)
    result["truth"][unknownName(k)] = world.true_offsets_deg[k + 1];
  nlohmann::json breakdown = nlohmann::json::array();
  for (const PoseRecord& r : outcome.records)
    breakdown.push_back({{"pose", r.index + 1},
                         {"move_s", r.servo.move_s},
                         {"acquisition_s", r.servo.acquisition_s},
                         {"servo_s", r.servo.servo_s},
                         {"servo_moves", r.servo.moves},
                         {"final_error_um", r.servo.final_error_um}});
  result["pose_breakdown"] = breakdown;
  store.writeResult(session.id, result);

  if (json) {
    std::cout << result.dump(2) << "\n";
  } else {
    std::cout << toText(*outcome.report);
    std::printf("\n%-12s %12s %12s %12s\n", "offset", "identified", "truth", "error");
    for (int k = 0; k < kOffsetCount; ++k) {
      const auto& e = outcome.report->parameters[k];
      const double truth = world.true_offsets_deg[k + 1];
      std::printf("%-12s %12.5f %12.5f %+12.5f  (%.1f sigma)\n", e.name.c_str(), e.value, truth,
                  e.value - truth, std::abs(e.value - truth) / e.sigma);
    }
    std::printf("cell time %.1f s for %d poses; session %s\n", cell_time_s, n, session.dir.c_str());
  }
  return kOk;
}

}  // namespace
}  // namespace zerocal

int main(int argc, char** argv) {
  using namespace zerocal;
  CLI::App app{
      "zerocald: the zerocal cell daemon. This version runs one calibration on the "
      "simulated cell and exits (--sim --once)."};
  ConfigSources sources;
  bool sim = false, once = false, json = false;
  std::optional<std::uint64_t> seed;
  std::string data_dir;
  app.add_option("--config", sources.config_path, "main configuration file")
      ->default_str(kDefaultConfigPath);
  app.add_option("--config-dir", sources.drop_in_dir, "drop-in folder of *.yaml files")
      ->default_str(kDefaultDropInDir);
  app.add_option("--set", sources.overrides, "override one key: section.key=value (repeatable)");
  app.add_flag("--sim", sim, "use the in-process simulated cell (backend.kind=sim)");
  app.add_flag("--once", once, "run one calibration, then exit");
  app.add_option("--seed", seed, "simulated world from this seed (backend.sim_seed)");
  app.add_option("--data-dir", data_dir, "where session folders go (session.data_dir)");
  app.add_flag("--json", json, "print the result as one JSON object");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  sources.config_path_explicit = app.count("--config") > 0;
  sources.drop_in_dir_explicit = app.count("--config-dir") > 0;
  if (sim) sources.overrides.push_back("backend.kind=sim");
  if (seed) sources.overrides.push_back("backend.sim_seed=" + std::to_string(*seed));
  if (!data_dir.empty()) sources.overrides.push_back("session.data_dir=\"" + data_dir + "\"");
  if (!once) {
    std::cerr << "zerocald: only --once is available in this version: the long-running service "
                 "(control port, sessions on request) is not built yet\n";
    return 2;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    const DaemonConfig cfg = loadDaemonConfig(sources);
    initLogging(cfg.logging);
    return runOnce(cfg, json);
  } catch (const ConfigError& e) {
    std::cerr << "zerocald: " << e.what() << "\n";
    return 2;
  } catch (const InputError& e) {
    std::cerr << "zerocald: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "zerocald: " << e.what() << "\n";
    return 1;
  }
}
