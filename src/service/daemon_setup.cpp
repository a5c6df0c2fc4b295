#include "zerocal/service/daemon_setup.h"

#include "zerocal/report/session_report.h"
#include "zerocal/service/cell_factory.h"
#include "zerocal/service/hardware_backend.h"
#include "zerocal/sim/sim_backend.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

RunSettings runSettingsOf(const DaemonConfig& config) {
  RunSettings s;
  s.servo = config.servo;
  s.servo.limit_margin_deg = config.controller.section().motion().limit_margin_deg;
  s.solve.noise_mm = config.session.noise_mm;
  s.solve.required_accuracy_deg = config.session.required_accuracy_deg;
  return s;
}

namespace {

// The configured controller's link, pointed at a simulated controller.
sim::SimLinkFactory linkTo(const ControllerConfig& controller) {
  return [controller](const LinkEndpoint& at) { return makeControllerConnection(controller, &at); };
}

}  // namespace

std::unique_ptr<CellBackend> makeBackend(const DaemonConfig& cfg) {
  if (cfg.backend.kind == BackendKind::kHardware) return std::make_unique<HardwareBackend>(cfg);
  const std::uint64_t seed = cfg.backend.sim_seed.value_or(1);
  sim::SimulatedCellOptions o = sim::seededCellOptions(
      seed, cfg.backend.sim_ideal_world ? WorldKind::kIdeal : WorldKind::kRealistic);
  if (!cfg.backend.sim_ideal_world) {
    o.world.gross.stray_light_rate = cfg.backend.sim_gross_rate;
    o.world.gross.unsettled_rate = cfg.backend.sim_gross_rate;
  }
  if (!cfg.backend.sim_world.empty()) o.world = loadWorld(cfg.backend.sim_world);
  // A motor replaced: on top of the world's offsets, in the truth too (validated with the
  // configuration; applyZeroChange throws for what a caller's own configuration let through).
  applyZeroChange({cfg.backend.sim_zero_change_joint, cfg.backend.sim_zero_change_deg}, &o.world);
  // The PSD or the laser re-mounted since an earlier session (validated as the zero change).
  applyRemount({cfg.backend.sim_psd_moved_mm, cfg.backend.sim_psd_turned_deg},
               {cfg.backend.sim_laser_moved_mm, cfg.backend.sim_laser_turned_deg}, &o.world);
  if (!cfg.backend.sim_host.empty()) {
    // The controller in an external zerocal-sim, the board in-process (sim::ExternalSimBackend).
    sim::ExternalSimOptions e;
    e.world_source = cfg.backend.sim_world.empty()
                         ? "backend.sim_seed " + std::to_string(seed) +
                               (cfg.backend.sim_ideal_world ? ", ideal world" : "")
                         : "backend.sim_world " + cfg.backend.sim_world;
    e.at = {cfg.backend.sim_host, cfg.backend.sim_port, {}};
    e.link = linkTo(cfg.controller);
    e.world = std::move(o.world);
    e.psd.seed = o.psd.seed;
    return std::make_unique<sim::ExternalSimBackend>(std::move(e));
  }
  o.pace = cfg.backend.sim_pace;
  o.warm_s = cfg.backend.sim_warm_s;  // the arm's thermal state when this daemon starts it
  o.motion.overhead_s = cfg.backend.sim_move_overhead_s;
  // The controller section applies to the simulated controller as to a real one; only where the
  // controller listens and how quickly to retry come from the simulated cell.
  // Each session its own noise, the world's errors fixed: the first session in a data folder
  // draws from the seed's (or the world file's noise.seed, else 1: what a world always drew from),
  // each later one from a seed mixed from it and the number of sessions before it
  // (docs/simulated-cell.md); its truth names the seed.
  sim::SessionNoise noise;
  noise.first = cfg.backend.sim_world.empty() ? seed : o.world.noise.seed.value_or(1);
  noise.sessions_before = SessionStore(cfg.session.data_dir).list().size();
  return std::make_unique<sim::SimBackend>(std::move(o), linkTo(cfg.controller), noise);
}

ManagerSettings managerSettingsOf(const DaemonConfig& cfg) {
  ManagerSettings s;
  s.session = cfg.session;
  s.run = runSettingsOf(cfg);
  if (cfg.backend.kind == BackendKind::kHardware) {
    const auto& t = cfg.session.target_mm;
    s.target_mm = Eigen::Vector3d(t[0], t[1], t[2]);
  }
  s.config_snapshot = configToJson(cfg);
  const ControllerMotion motion = cfg.controller.section().motion();
  if (cfg.backend.kind == BackendKind::kSim && cfg.backend.sim_host.empty()) {
    s.move_overhead = MoveOverhead{cfg.backend.sim_move_overhead_s, motion.settle_s};
  }
  s.travel_s = motion.travel_s;
  s.write_reports = [](const std::string& dir, const std::vector<record::HistoryEntry>& history) {
    report::writeSessionReport(dir, history);
  };
  s.controller_restart_timeout = motion.restart_timeout;
  return s;
}

}  // namespace zerocal::service
