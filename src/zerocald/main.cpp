// zerocald: the cell daemon. Reads its configuration (every error reported, none started with),
// picks the backend (the IRC5 plus the USB-1408FS, or the simulated cell in-process), and either
// runs one calibration and exits (--once), or serves the control port until SIGINT/SIGTERM.
// On a signal the running session is aborted: the robot is stopped after the move in progress,
// every recorded pose is already on disk, and the daemon exits 0.
//
// Exit codes: 0 calibrated (or stopped cleanly); 1 unexpected failure; 2 bad configuration or
// usage; 3 the session faulted or was aborted (the journal keeps every recorded pose); 4 the plan
// cannot identify delta2..delta5.
#include <CLI/CLI.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <cstdio>
#include <iostream>

#include "zerocal/calib/format.h"
#include "zerocal/control/line_connection.h"
#include "zerocal/control/server.h"
#include "zerocal/control/token.h"
#include "zerocal/daemon/config.h"
#include "zerocal/daemon/logging.h"
#include "zerocal/daemon/systemd.h"
#include "zerocal/error.h"
#include "zerocal/record/sqlite_record.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/store/data_folder_lock.h"
#include "zerocal/store/session_store.h"
#include "zerocal/web/web_server.h"

namespace zerocal {
namespace {

namespace asio = boost::asio;
using service::SessionManager;
using service::SessionState;

enum ExitCode { kOk = 0, kFailure = 1, kBadInput = 2, kStopped = 3, kNotIdentifiable = 4 };

// No step of a session goes this long without progress (a phase, a PSD reading, a pose): the
// longest is one move within its deadline (estimated duration x controller.irc5.move_timeout_factor
// + margin, seconds to tens of seconds) or a connect with its retries. Longer, the worker is stuck.
constexpr std::chrono::seconds kWorkerStallLimit{120};

// Under systemd's watchdog (WatchdogSec=): why the worker is stuck, or nullopt while it is not.
std::optional<std::string> stuckWorker(const SessionManager& manager) {
  const auto stalled = manager.workerStalledFor();
  if (stalled <= kWorkerStallLimit) return std::nullopt;
  return "the session worker (and its servo) made no progress for " +
         std::to_string(std::chrono::duration_cast<std::chrono::seconds>(stalled).count()) + " s";
}

void logUnfinished(SessionManager& manager) {
  auto log = makeLogger("session");
  for (const SessionInfo& s : manager.sessions())
    if (!s.finished && s.damaged.empty())
      log->warn(
          "session {} is unfinished ({} of {} poses recorded): `zerocal resume {}` "
          "continues it",
          s.id, s.recorded_poses, s.planned_poses, s.id);
}

// The robot's record in the data folder (docs/record.md), opened, rebuilt or caught up with the
// session folders, and what that took said in the log. Throws FileError when it cannot be kept
// (a newer zerocal's record: the message says how to go on).
std::unique_ptr<record::SqliteRecord> openTheRecord(const std::string& data_dir) {
  auto log = makeLogger("record");
  record::OpenedRecord opened = record::openRecord(SessionStore(data_dir), data_dir);
  if (!opened.damage.empty())
    log->error("the robot's record was damaged ({}){}; rebuilt from the session folders",
               opened.damage, opened.moved_aside.empty() ? "" : ", kept as " + opened.moved_aside);
  if (opened.migrated_from > 0)
    log->info("the robot's record migrated from schema version {} to {}", opened.migrated_from,
              record::kRecordSchemaVersion);
  if (opened.built)
    log->info("the robot's record built from the session folders: {} sessions, {} apply events",
              opened.filled.sessions, opened.filled.events);
  else if (opened.filled.sessions > 0 || opened.filled.events > 0)
    log->warn("the robot's record lacked {} sessions and {} apply events; recorded them now",
              opened.filled.sessions, opened.filled.events);
  for (const std::string& problem : opened.filled.problems)
    log->warn("not in the robot's record: {}", problem);
  return std::move(opened.record);
}

// What --once runs: the session's kind and reference, and whether its result is applied.
struct OnceOptions {
  bool json = false;
  bool even_if_not_usable = false;
  std::string kind;  // empty: a calibration
  std::string reference;
  bool apply = false;
};

// Applies the session's result online (its backup, verification and rollback), as `zerocal apply
// --confirm` does; the outcome on stderr. kOk when verified.
int applyOnce(SessionManager& manager, const std::string& id) {
  try {
    manager.apply({id, true});
  } catch (const service::Refused& e) {
    std::cerr << "zerocald: not applied: " << e.what() << "\n";
    return kStopped;
  }
  const service::SessionStatus end = manager.waitIdle();
  std::fprintf(stderr, "apply: %s\n", end.apply.c_str());
  return end.apply.rfind("session " + id + " verified", 0) == 0 ? kOk : kStopped;
}

// One session, then exit; progress on stderr, the result on stdout.
int runOnce(SessionManager& manager, asio::io_context& io, const OnceOptions& once) {
  const bool json = once.json;
  manager.setEventSink([&io](const service::SessionEvent& event) {
    if (const auto* plan = std::get_if<service::PlanEvent>(&event)) {
      std::fprintf(stderr, "plan: %s\n", plan->description.c_str());
      for (std::size_t k = 0; k < plan->predicted_sigma_deg.size(); ++k)
        std::fprintf(stderr, "  predicted sigma %-12s %s deg\n",
                     unknownName(static_cast<int>(k)).c_str(),
                     nlohmann::json(plan->predicted_sigma_deg[k]).dump().c_str());
    } else if (const auto* pose = std::get_if<service::PoseEvent>(&event)) {
      if (pose->record.measured())
        std::fprintf(stderr, "pose %d of %d recorded: %d servo moves, %.2f um from the aim point\n",
                     pose->record.planIndex() + 1, pose->pose_count, pose->record.servo.moves,
                     pose->record.servo.final_error_um);
      else
        std::fprintf(stderr, "pose %d of %d skipped: %s\n", pose->record.planIndex() + 1,
                     pose->pose_count, pose->record.skipped.c_str());
    } else if (const auto* placement = std::get_if<service::PlacementEvent>(&event)) {
      std::fprintf(stderr, "PSD placement %d of %d: %s\n", placement->placement,
                   placement->placement_count, placement->message.c_str());
    } else if (const auto* state = std::get_if<service::StateEvent>(&event)) {
      if (!service::isActive(state->state) && state->state != SessionState::kIdle)
        asio::post(io, [&io] { io.stop(); });
    }
  });
  try {
    service::StartRequest request = manager.defaultRequest();
    request.even_if_not_usable = once.even_if_not_usable;
    if (!once.kind.empty())
      request.kind = once.kind == "calibrate" ? SessionKind::kCalibration
                                              : sessionKindFromName(once.kind, "--kind");
    request.reference = once.reference;
    manager.start(request);
  } catch (const service::Refused& e) {
    std::cerr << "zerocald: " << e.what() << "\n";
    if (e.code() == "unrecovered") return kStopped;
    return e.code() == "not_identifiable" || e.code() == "not_accurate" ? kNotIdentifiable
                                                                        : kBadInput;
  }
  io.run();  // until the session ends or a signal aborts it
  const service::SessionStatus status = manager.waitIdle();
  if (status.state != SessionState::kDone) {
    std::cerr << "zerocald: session " << status.session_id << " " << stateName(status.state) << ": "
              << status.message << "\n";
    return kStopped;
  }
  const ResultFile result = manager.result(status.session_id);
  const int applied = once.apply ? applyOnce(manager, status.session_id) : kOk;
  if (json) {
    std::cout << toJson(result).dump(2) << "\n";
    return applied;
  }
  // Against a reference, the truth is the change of the simulated world's zeros since then.
  std::optional<std::array<double, 4>> truth;
  if (result.truth) truth = result.truth->offsets_deg;
  if (truth && !result.reference.empty()) {
    const ResultFile reference = manager.result(result.reference);
    if (reference.truth)
      for (int k = 0; k < kOffsetCount; ++k) (*truth)[k] -= reference.truth->offsets_deg[k];
    else
      truth.reset();
  }
  std::printf("%-12s %12s %10s %24s", "offset", result.reference.empty() ? "identified" : "change",
              "sigma", "95% interval");
  if (truth) std::printf(" %12s %12s", "truth", "error");
  std::printf("\n");
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& e = result.report.parameters[k];  // delta2..delta5
    if (!e.identifiable) {
      std::printf("%-12s %12s\n", e.name.c_str(), "not identifiable");
      continue;
    }
    std::printf("%-12s %12.5f %10.5f  [%10.5f, %10.5f]", e.name.c_str(), e.value, e.sigma,
                e.ci95_low, e.ci95_high);
    if (truth)
      std::printf(" %12.5f %+12.5f (%.1f sigma)", (*truth)[k], e.value - (*truth)[k],
                  std::abs(e.value - (*truth)[k]) / e.sigma);
    std::printf("\n");
  }
  std::printf("cell time %.1f s for %d poses; %s %s\n", result.cell_time_s.value_or(0),
              status.pose_count, sessionKindName(result.kind), status.session_id.c_str());
  if (!result.reference.empty())
    std::printf("the offsets are the change since reference %s\n", result.reference.c_str());
  if (result.check) std::printf("check: %s\n", result.check->summary.c_str());
  std::printf("verdict: %s\n", result.report.verdict.usable ? "usable" : "NOT USABLE");
  for (const std::string& reason : result.report.verdict.reasons)
    std::printf("  %s\n", reason.c_str());
  return applied;
}

}  // namespace
}  // namespace zerocal

int main(int argc, char** argv) {
  using namespace zerocal;
  CLI::App app{
      "zerocald: the zerocal cell daemon. Serves the control port (control.bind_address:port, "
      "token in control.token_file; docs/protocol.md) and, with web.enabled (by default with "
      "--sim), the shop-floor terminal in a browser (web.bind_address:port, default "
      "127.0.0.1:7451; docs/web.md), and runs the calibration sessions that "
      "`zerocal start` asks for on the configured cell, until SIGINT or SIGTERM. With --once, runs "
      "one calibration as configured and exits. docs/daemon.md explains it."};
  app.set_version_flag("--version", "zerocald " + std::string(PROJECT_VERSION));
  ConfigSources sources;
  bool sim = false, once = false;
  OnceOptions once_options;
  std::optional<std::uint64_t> seed;
  std::string data_dir;
  app.add_option("--config", sources.config_path, "main configuration file")
      ->default_str(kDefaultConfigPath);
  app.add_option("--config-dir", sources.drop_in_dir, "drop-in folder of *.yaml files")
      ->default_str(kDefaultDropInDir);
  app.add_option("--set", sources.overrides, "override one key: section.key=value (repeatable)");
  app.add_flag("--sim", sim, "use the in-process simulated cell (backend.kind=sim)");
  app.add_flag("--once", once, "run one calibration as configured (session.*), then exit");
  app.add_option("--seed", seed, "simulated world from this seed (backend.sim_seed)");
  bool ideal_world = false;
  app.add_flag("--ideal-world", ideal_world,
               "the seed's ideal world instead of its realistic one (backend.sim_ideal_world; "
               "docs/simulated-cell.md)");
  app.add_option("--data-dir", data_dir, "where session folders go (session.data_dir)");
  app.add_flag("--json", once_options.json, "--once: print the result as one JSON object");
  app.add_option("--kind", once_options.kind,
                 "--once: calibrate (default), reference, check or restore (docs/record.md)")
      ->check(CLI::IsMember({"calibrate", "reference", "check", "restore"}));
  app.add_option("--reference", once_options.reference,
                 "--once: the reference a check or restore compares with (default the latest)");
  app.add_flag("--apply", once_options.apply,
               "--once: apply a usable result online (backup, verification, rollback), as "
               "`zerocal apply --confirm`; exits 3 unless it is verified");
  app.add_flag("--even-if-not-usable", once_options.even_if_not_usable,
               "--once: calibrate even when the plan is predicted not to determine every offset "
               "to session.required_accuracy_deg (refused otherwise, before anything moves)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  sources.config_path_explicit = app.count("--config") > 0;
  sources.drop_in_dir_explicit = app.count("--config-dir") > 0;
  if (sim) sources.overrides.push_back("backend.kind=sim");
  if (seed) sources.overrides.push_back("backend.sim_seed=" + std::to_string(*seed));
  if (ideal_world) sources.overrides.push_back("backend.sim_ideal_world=true");
  if (!data_dir.empty()) sources.overrides.push_back("session.data_dir=\"" + data_dir + "\"");
  try {
    const DaemonConfig cfg = loadDaemonConfig(sources);
    initLogging(cfg.logging);
    auto log = makeLogger("zerocald");
    // The io_context outlives the manager: the manager's worker posts events into it until the
    // manager's destructor has joined the worker.
    asio::io_context io;
    // One daemon per data folder, held until this one ends: before the cell is opened or anything
    // in the folder touched.
    const DataFolderLock data_folder_lock(cfg.session.data_dir);
    std::unique_ptr<CellBackend> backend = service::makeBackend(cfg);
    service::ManagerSettings settings = service::managerSettingsOf(cfg);
    if (once && cfg.session.placements > 1) {
      // Nobody continues a --once session: the simulated cell moves its PSD itself; a real
      // cell's needs a technician at the control port.
      if (cfg.backend.kind != BackendKind::kSim)
        throw ConfigError("configuration", {"session.placements: --once has nobody to move the PSD "
                                            "between placements; serve the control port (without "
                                            "--once) and `zerocal continue` at each placement"});
      settings.unattended_placements = true;
    }
    // What a write cut short (a full disk, a kill) left behind is no session's file.
    for (const std::string& stale : SessionStore(cfg.session.data_dir).removeStaleTemporaries())
      log->warn("removed {}, left by a write that did not complete", stale);
    // Outlives the manager, which records into it.
    const std::unique_ptr<record::SqliteRecord> robot_record = openTheRecord(cfg.session.data_dir);
    settings.record = robot_record.get();
    service::SessionManager manager(*backend, std::move(settings));
    log->info("backend {}; sessions in {}", backend->name(), cfg.session.data_dir);
    logUnfinished(manager);

    asio::signal_set signals(io, SIGINT, SIGTERM);
    if (once) {
      signals.async_wait([&](const boost::system::error_code& ec, int signal) {
        if (ec) return;
        log->warn("signal {}: aborting the session, stopping the robot", signal);
        manager.abort();  // the aborted session's end stops the io_context
      });
      // A calibration of its own runs on the controller's present values: only once an apply
      // interrupted earlier is recovered (else the start is refused and says what to check).
      if (manager.recoverInterruptedApplies() > 0) manager.waitIdle();
      return runOnce(manager, io, once_options);
    }

    // Before the port opens: an apply the daemon was stopped in is restored first (the board is
    // busy until then, the status says so).
    if (const int interrupted = manager.recoverInterruptedApplies(); interrupted > 0)
      log->warn("{} interrupted apply(s) found: restoring the backed-up values", interrupted);
    control::ServerOptions options = cfg.control;  // the control section is the server's options
    try {
      options.token = control::loadToken(options.token_file);
    } catch (const Error& e) {
      // What to do, not only what is missing: the first run of `zerocald --sim` meets it.
      const std::string make_one =
          options.token_file.empty()
              ? "; make one (umask 077; head -c 24 /dev/urandom | base64 > FILE) and give it "
                "with --set control.token_file=FILE or in the configuration (docs/daemon.md)"
              : "";
      throw ConfigError("configuration",
                        {std::string("control.token_file: ") + e.what() + make_one});
    }
    if (!options.operator_token_file.empty()) {
      try {
        options.operator_token = control::loadToken(options.operator_token_file);
      } catch (const Error& e) {
        throw ConfigError("configuration",
                          {std::string("control.operator_token_file: ") + e.what()});
      }
      if (control::tokensEqual(options.operator_token, options.token))
        throw ConfigError("configuration",
                          {"control.operator_token_file: holds the engineer's token "
                           "(control.token_file): an operator's login must have a token of its "
                           "own"});
      log->info("operator logins (checks, abort) with the token in {}",
                options.operator_token_file);
    }
    options.daemon_version = PROJECT_VERSION;
    // What `start` leaves out comes from the session section. One hub serves the TCP port and
    // the web terminal's WebSocket: one event sink, the same commands and authentication.
    const auto hub =
        control::ProtocolHub::create(io, manager, std::move(options), manager.defaultRequest());
    control::ControlServer server(hub);
    try {
      server.start();
    } catch (const std::exception& e) {  // address in use, not an address of this machine
      throw ConfigError("configuration", {"control port " + cfg.control.bind_address + ":" +
                                          std::to_string(cfg.control.port) + ": " + e.what()});
    }
    std::optional<web::WebServer> web_server;
    if (webEnabled(cfg)) {
      try {
        web::WebOptions web_options = cfg.web;
        web_options.sessions_dir = cfg.session.data_dir;  // the reports the terminal serves
        web_server.emplace(io, hub, std::move(web_options));
        web_server->start();
      } catch (const std::exception& e) {
        throw ConfigError("zerocald", {"web terminal " + cfg.web.bind_address + ":" +
                                       std::to_string(cfg.web.port) + ": " + e.what()});
      }
    }
    // Ready for systemd (Type=notify) only now that the port accepts connections.
    std::string serving = "serving " + cfg.control.bind_address + ":" +
                          std::to_string(server.port()) + " (" + backend->name() + " cell)";
    if (web_server)
      serving += std::string(", web terminal ") +
                 (cfg.web.tls_certificate.empty() ? "http://" : "https://") + cfg.web.bind_address +
                 ":" + std::to_string(web_server->port()) + "/";
    notifyReady(serving);
    std::optional<Watchdog> watchdog;
    if (const auto interval = watchdogInterval()) {
      watchdog.emplace(io, *interval, [&manager] { return stuckWorker(manager); });
      watchdog->start();
      log->info("systemd watchdog every {} ms; a worker stuck for {} s starves it",
                interval->count() / 1000, kWorkerStallLimit.count());
    }
    signals.async_wait([&](const boost::system::error_code& ec, int signal) {
      if (ec) return;
      log->warn("signal {}: aborting any session, stopping the robot, closing the port", signal);
      notifyStopping("stopping: aborting any session, stopping the robot");
      if (watchdog) watchdog->stop();
      manager.abort();
      server.stop();
      if (web_server) web_server->stop();
      hub->stop();
      io.stop();
    });
    io.run();
    hub->stop();  // the event sink cleared before the manager goes
    const service::SessionStatus last = manager.waitIdle();  // the robot stopped, journal closed
    log->info("stopped; the last session {} is {}", last.session_id, stateName(last.state));
    return kOk;
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
