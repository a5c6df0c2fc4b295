#include "zerocal/service/session_runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "zerocal/calib/change.h"
#include "zerocal/calib/solver.h"
#include "zerocal/daemon/logging.h"
#include "zerocal/service/result_assembly.h"
#include "zerocal/service/session_recording.h"

namespace zerocal::service {
namespace {

// A simulated session's whole world, beside its result (docs/simulated-cell.md).
constexpr const char* kTruthWorldFile = "truth-world.yaml";
// A calibration's calibrated model, beside its result (docs/record.md).
constexpr const char* kModelFile = "model.yaml";

// The run's PSD reader, passing each reading on to the live slot, and its time to the watchdog's
// progress mark (an atomic store: nothing that allocates or locks in the servo cycle).
class ObservedReader final : public PsdReader {
 public:
  ObservedReader(PsdReader& inner, LiveReadingSlot& slot, SessionWorker& worker)
      : inner_(inner), slot_(slot), worker_(worker) {}
  PsdReading read() override {
    const PsdReading r = inner_.read();
    slot_.store(r);
    worker_.markProgress();
    return r;
  }

 private:
  PsdReader& inner_;
  LiveReadingSlot& slot_;
  SessionWorker& worker_;
};

// The cell time the recorded poses took: each one's planned move, search, servo and settling.
double recordedCellTimeS(const std::vector<PoseRecord>& records) {
  double t = 0;
  for (const PoseRecord& r : records)
    if (r.measured())
      t += r.servo.move_s + r.servo.acquisition_s + r.servo.servo_s + r.servo.settle_s;
  return t;
}

// Each measured pose's 0-based position among the reference's fit poses: plan pose p re-measures
// the reference's plan pose reference_poses[p].
std::vector<int> pairsOf(const Reference& reference, const std::vector<int>& reference_poses,
                         const std::vector<int>& plan_indices) {
  std::vector<int> pairs;
  for (const int p : plan_indices) {
    if (p < 0 || p >= static_cast<int>(reference_poses.size()))
      throw InputError("plan pose " + std::to_string(p + 1) + " has no reference pose");
    const auto it = std::find(reference.plan_poses.begin(), reference.plan_poses.end(),
                              reference_poses[static_cast<std::size_t>(p)]);
    if (it == reference.plan_poses.end())
      throw InputError("plan pose " + std::to_string(p + 1) + " re-measures reference pose " +
                       std::to_string(reference_poses[static_cast<std::size_t>(p)]) +
                       ", which reference " + reference.id + "'s solve did not use");
    pairs.push_back(static_cast<int>(it - reference.plan_poses.begin()));
  }
  return pairs;
}

// The zeros that moved since the robot's latest comparison with `reference` before session `id`
// (a check, a restore, a verification against it), by more than the history explains.
std::vector<Drift> driftSinceLastComparison(const SessionStore& store, const std::string& id,
                                            const Reference& reference, const SolveReport& now) {
  const auto changes = [](const SolveReport& r, std::vector<double>& value,
                          std::vector<double>& sigma) {
    for (int k = 0; k < kOffsetCount && k < static_cast<int>(r.parameters.size()); ++k) {
      const ParameterEstimate& p = r.parameters[static_cast<std::size_t>(k)];
      value.push_back(p.identifiable ? p.value : std::nan(""));
      sigma.push_back(p.identifiable ? p.sigma : std::nan(""));
    }
  };
  const std::vector<SessionInfo> sessions = store.list();  // oldest first
  for (auto s = sessions.rbegin(); s != sessions.rend(); ++s) {
    if (s->id >= id || !s->finished) continue;
    try {
      const ResultFile then = store.readResult(s->id);
      if (then.reference != reference.id || !then.report.converged) continue;
      std::vector<double> then_deg, then_sigma, now_deg, now_sigma;
      changes(then.report, then_deg, then_sigma);
      changes(now, now_deg, now_sigma);
      return driftBetween(s->id, then_deg, then_sigma, now_deg, now_sigma);
    } catch (const Error&) {
      continue;  // an unreadable result is no history
    }
  }
  return {};
}

// Why a session on the robot the controller names (`controller`) may not use `what`, recorded of
// the robot `recorded`: another type or serial. Empty when it may (or nothing was recorded).
std::string otherRobot(const RobotInfo& controller, const RobotInfo& recorded,
                       const std::string& what, const std::string& rule) {
  if (recorded.serial.empty() ||
      (controller.serial == recorded.serial && controller.robot_type == recorded.robot_type))
    return "";
  return "the controller names its robot " + controller.robot_type + " serial " +
         controller.serial + ", and " + what + " is of " + recorded.robot_type + " serial " +
         recorded.serial + ": a robot is " + rule;
}

SessionState stateOf(RunPhase phase) {
  switch (phase) {
    case RunPhase::kMoving:
      return SessionState::kMoving;
    case RunPhase::kServoing:
      return SessionState::kServoing;
    case RunPhase::kRecording:
      return SessionState::kRecording;
    case RunPhase::kSolving:
      return SessionState::kSolving;
  }
  return SessionState::kMoving;
}

std::int64_t unixSeconds() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

SessionRunner::SessionRunner(CellConnection& connection, SessionBoard& board, SessionWorker& worker,
                             SessionStore& store, const RequestPlanner& planner,
                             const CellKnowledge& knowledge, LiveReadingSlot& live,
                             const ManagerSettings& settings)
    : connection_(connection),
      board_(board),
      worker_(worker),
      store_(store),
      planner_(planner),
      knowledge_(knowledge),
      live_(live),
      settings_(settings) {}

void SessionRunner::run(const RunRequest& request) {
  switch (request.kind) {
    case SessionKind::kCalibration:
    case SessionKind::kVerification:
    case SessionKind::kReference:
    case SessionKind::kCheck:
    case SessionKind::kRestore:
      return runMeasurement(request);
  }
  finish(SessionState::kFaulted,
         std::string("a session of kind ") + sessionKindName(request.kind) + " cannot be run");
}

void SessionRunner::setPhase(SessionState state, int pose) {
  worker_.markProgress();
  board_.setPhase(state, pose);
}

void SessionRunner::finish(SessionState state, const std::string& message) {
  auto log = makeLogger("session");
  if (state != SessionState::kDone) connection_.stopRobot();
  const std::string id = board_.status().session_id;
  if (state == SessionState::kDone)
    log->info("session {} done", id);
  else
    log->error("session {} {}: {} (every recorded pose is in {})", id, stateName(state), message,
               store_.journalPath(id));
  board_.finish(state, message);
}

void SessionRunner::runMeasurement(const RunRequest& request) {
  auto log = makeLogger("session");
  const std::string& id = request.id;
  const LoggedSession logged(id);
  const RunPlan& run_plan = request.plan;
  // Every placement's planned centre, placement 1's first: the target alone with one.
  const std::vector<Eigen::Vector3d> centres =
      run_plan.centres.empty() ? std::vector<Eigen::Vector3d>{run_plan.target} : run_plan.centres;
  const int placement_count = static_cast<int>(centres.size());
  if (board_.abortRequested()) return finish(SessionState::kAborted, "aborted before connecting");
  try {
    if (!connection_.connected()) {
      setPhase(SessionState::kConnecting, 0);
      log->info("connecting to the {} cell", connection_.backendName());
      connection_.connect();
    }
  } catch (const std::exception& e) {
    return finish(SessionState::kFaulted, std::string("cannot connect to the cell: ") + e.what());
  }
  const CellIdentity identity = connection_.identify(id);
  logged.setRobot(identity.robot.serial);
  // Measured against a reference: its poses and fit, and the robot must be the reference's.
  std::optional<Reference> reference;
  std::vector<int> reference_poses;
  // Planned with an earlier calibration's calibrated model: solved with it too, and the robot
  // must be the one it calibrated.
  std::optional<CalibratedModel> model;
  try {
    const SessionFile session = store_.readSession(id);
    if (!session.reference.empty()) {
      reference = loadComparedWith(store_, session);
      reference_poses = session.reference_poses;
    }
    if (!session.model_from.empty()) model = loadCalibratedModel(store_, session.model_from);
  } catch (const std::exception& e) {
    return finish(SessionState::kFaulted, e.what());
  }
  std::string other_robot;
  if (reference)
    other_robot = otherRobot(identity.robot, reference->robot, "reference " + reference->id,
                             "compared only with its own reference");
  if (model && other_robot.empty())
    other_robot =
        otherRobot(identity.robot, model->origin, "the calibrated model of session " + model->id,
                   "solved only with its own model");
  if (!other_robot.empty()) return finish(SessionState::kFaulted, other_robot);
  // The cell as this session's solve knows it: the daemon's robot file, or the calibrated model.
  CellModel cell_model = knowledge_.cell;
  if (model) cell_model.robot = model->robot;
  ConnectedCell& cell = connection_.cell();
  cell.beginSession();

  std::optional<RunOutcome> outcome;
  double cell_time_s = 0;
  try {
    Journal journal(store_.journalPath(id));
    if (!journal.dropped().empty())
      log->warn("session {}: {} (the pose will be measured again)", id, journal.dropped());
    RunSettings run_settings = settings_.run;
    run_settings.solve.noise_mm = run_plan.noise_mm;
    run_settings.solve.model = cell_model.robot.tolerance;  // what its robot model admits
    // A reference claims nothing of the absolute zeros: its offsets are not judged by the
    // required accuracy, only its fit by the noise.
    if (request.kind == SessionKind::kReference)
      run_settings.solve.required_accuracy_deg = run_settings.solve.max_offset_deg;
    if (reference)
      run_settings.solver = [this, &request, &reference, &reference_poses](
                                const std::vector<Pose>& poses,
                                const std::vector<int>& plan_indices, const SolveOptions& options) {
        ChangeOptions change = planner_.changeOptions(request.kind);
        change.solve = options;
        SolveReport report =
            solveChange(knowledge_.cell, reference->fit, poses,
                        pairsOf(*reference, reference_poses, plan_indices), change);
        // A check whose verdict stands without the poses it left out (a pass or a named joint,
        // judged on the others with their sigmas) has no use for measuring them again: a check
        // is meant to take half a minute. A marginal one measures them again.
        if (request.kind == SessionKind::kCheck && !report.remeasure.empty() &&
            judgeCheck(report, options.required_accuracy_deg).outcome !=
                CheckJudgement::Outcome::kMarginal)
          report.remeasure.clear();
        return report;
      };
    // A dropped controller connection or an unplugged board is recovered by reopening it; the
    // pose in progress (not journalled) is then measured again from its planned move.
    run_settings.reconnect_link = [&cell] { cell.reconnectRobot(); };
    run_settings.reopen_sensor = [&cell] { cell.reopenPsd(); };
    CalibrationRun run(cell_model, run_plan.target, run_plan.poses, run_settings, journal);
    run.found_before = request.found_before;
    if (reference) run.earlier = reference->fit.poses;
    if (request.place_next) run.placeNext(*request.place_next);
    // The cell's PSD where the journal has it: the simulated cell moves its detector there (back
    // to placement 1 for a session of one); on a real cell the technician has, and nothing
    // happens. Again at every placement an unattended run goes on to.
    const auto placed = [&](int placement) {
      cell.placePsd(placement, centres);
      board_.update([&](SessionStatus& s) { s.placement = placement_count > 1 ? placement : 0; });
    };
    if (reference && reference->placement > 1)
      // A verification re-measures a calibration's last placement, where the PSD stands after
      // it: the simulated cell keeps its detector there too.
      cell.placePsd(reference->placement, reference->placement_centres_mm);
    else
      placed(journal.placement());
    // A session resumed (after a PSD placement by the technician, or a restart) already spent
    // the cell time of the poses it recorded before: the journal's servo times say how much.
    const double start_s = cell.clock().nowS() - recordedCellTimeS(journal.records());
    run.on_phase = [this, &cell, start_s](int i, RunPhase phase) {
      // The cell's clock is the worker's to read: the status gets its time at each phase.
      const double elapsed_s = cell.clock().nowS() - start_s;
      board_.update([elapsed_s](SessionStatus& s) { s.cell_time_s = elapsed_s; });
      setPhase(stateOf(phase), i + 1);
    };
    run.on_remeasure = [this, &id, &log](const std::vector<int>& plan_indices) {
      RemeasureEvent event{id, {}};
      for (const int i : plan_indices) event.poses.push_back(i + 1);
      log->warn("session {}: the solve named poses {} as not fitting: measuring them again", id,
                nlohmann::json(event.poses).dump());
      board_.emit(event);
    };
    run.on_pose = [this, &id](const PoseRecord& r) {
      worker_.markProgress();
      PoseEvent event{id, 0, r};
      board_.update([&](SessionStatus& s) {
        s.recorded = r.index + 1;
        if (r.measured()) s.last_servo_error_um = r.servo.final_error_um;
        event.pose_count = s.pose_count;
      });
      board_.emit(event);
    };
    if (request.skip_index >= 0) {
      // resume() checked this pose is the next one and the plan identifiable without it.
      run.skipNextPose(request.skip_reason);
      log->warn("session {}: pose {} skipped ({})", id, request.skip_index + 1,
                request.skip_reason);
    }
    ObservedReader reader(cell.psd(), live_, worker_);
    outcome = run.run(cell.robot(), reader, cell.clock(), board_.abortRequested());
    while (outcome->state == RunState::kAwaitingPlacement && settings_.unattended_placements) {
      const int next = outcome->next_placement;
      log->info("session {}: no technician; the PSD goes on to placement {} at {}", id, next,
                centreText(centres[next - 1]));
      board_.emit(PlacementEvent{id, next, placement_count, centres[next - 1],
                                 "placement " + std::to_string(next) + " of " +
                                     std::to_string(placement_count) + " at its planned centre"});
      run.placeNext(centres[next - 1]);
      placed(next);
      RunOutcome then = run.run(cell.robot(), reader, cell.clock(), board_.abortRequested());
      then.resumed_from = outcome->resumed_from;
      then.reconnects += outcome->reconnects;
      then.reopens += outcome->reopens;
      outcome = std::move(then);
    }
    cell_time_s = cell.clock().nowS() - start_s;
  } catch (const std::exception& e) {
    connection_.drop();
    return finish(SessionState::kFaulted, e.what());
  }
  board_.update([&](SessionStatus& s) {
    s.cell_time_s = cell_time_s;
    s.resumed_from = outcome->resumed_from;
  });
  if (outcome->state == RunState::kAborted) return finish(SessionState::kAborted, outcome->message);
  if (outcome->state == RunState::kAwaitingPlacement) {
    const int next = outcome->next_placement;
    const Eigen::Vector3d& centre = centres[next - 1];
    const std::string message =
        "move the PSD to placement " + std::to_string(next) + " of " +
        std::to_string(placement_count) + ": its centre at " + centreText(centre) +
        " in the robot base frame, facing as before; then `zerocal continue` (with `--centre X Y "
        "Z` when it is taught elsewhere)";
    if (board_.awaitPlacement(next, centre, message)) {
      log->info("session {}: {}", id, message);
      board_.emit(PlacementEvent{id, next, placement_count, centre, message});
    } else {
      log->warn("session {} aborted before placement {}", id, next);
    }
    return;
  }
  if (outcome->state == RunState::kFaulted) {
    std::string message = outcome->message;
    // Only the next plan pose can be skipped (not one measured again after the plan).
    if (outcome->pose_at_fault && outcome->stopped_at >= 0 &&
        outcome->stopped_at == static_cast<int>(outcome->records.size())) {
      // Measuring this pose again would fail again: say whether the plan can do without it.
      const SkipAdvice skip =
          planner_.adviseSkip(id, run_plan, outcome->records, outcome->stopped_at);
      message += "; " + skip.advice;
      if (skip.skippable_pose > 0)
        board_.update([&](SessionStatus& s) { s.skippable_pose = skip.skippable_pose; });
    }
    finish(SessionState::kFaulted, message);
    connection_.drop();  // the links may be in any state: the next session connects afresh
    return;
  }

  RunFacts facts;
  facts.kind = request.kind;
  if (reference) {
    facts.reference = reference->id;
    const double bound = settings_.run.solve.required_accuracy_deg;
    if (request.kind == SessionKind::kCheck) facts.check = judgeCheck(*outcome->report, bound);
    if (request.kind == SessionKind::kRestore) refuseWithoutChange(*outcome->report);
    // A verification measures what an apply just changed: no drift of its own.
    if (request.kind != SessionKind::kVerification)
      facts.drift = driftSinceLastComparison(store_, id, *reference, *outcome->report);
    for (const Drift& d : facts.drift) log->warn("session {}: {}", id, d.summary);
  }
  facts.cell = ResultFile::Cell{identity.robot, knowledge_.psd_map};
  if (model) facts.model_from = model->id;
  facts.cal_offset_rad = identity.cal_offset_rad;
  facts.cell_time_s = cell_time_s;
  facts.finished_unix_s = unixSeconds();
  facts.truth_deg = cell.truthDeg();
  facts.truth_noise_seed = cell.truthNoiseSeed();
  facts.move_overhead = settings_.move_overhead;
  if (const auto world = cell.truthWorldYaml()) {
    try {
      store_.writeFile(id, kTruthWorldFile, *world);
      facts.truth_world_file = kTruthWorldFile;
    } catch (const std::exception& e) {
      return finish(SessionState::kFaulted, std::string("cannot write the truth: ") + e.what());
    }
  }
  const SolveReport& report = *outcome->report;
  if (request.kind == SessionKind::kCalibration && !report.placements.empty() &&
      report.verdict.usable) {
    // Identified links with their covariance: later one-placement calibrations of this robot
    // count what this one left of the link errors, not the robot file's tolerances.
    try {
      store_.writeFile(
          id, kModelFile,
          checkedRobotYaml(calibratedRobot(cell_model.robot, report),
                           "calibrated model of " + identity.robot.robot_type + " serial " +
                               identity.robot.serial + ", identified by zerocald session " + id +
                               " at " + std::to_string(report.placements.size()) +
                               " PSD placements"));
      facts.model_file = kModelFile;
    } catch (const std::exception& e) {
      return finish(SessionState::kFaulted,
                    std::string("cannot write the calibrated model: ") + e.what());
    }
  }
  complete(id, *outcome, std::move(facts));
}

void SessionRunner::complete(const std::string& id, const RunOutcome& outcome, RunFacts facts) {
  auto log = makeLogger("session");
  const ResultFile result = assembleResult(id, outcome, facts);
  try {
    store_.writeResult(id, result);
  } catch (const std::exception& e) {
    return finish(SessionState::kFaulted, std::string("cannot write the result: ") + e.what());
  }
  recordSession(settings_.record, store_, id);
  // The session is done with its result on disk whatever happens to the report, but whoever
  // follows it must learn that summary.txt and report.html are missing (a full disk, say).
  std::string report_error;
  if (settings_.write_reports) {
    try {
      settings_.write_reports(store_.sessionDir(id), robotHistory(settings_.record, result));
    } catch (const std::exception& e) {
      report_error = e.what();
      log->error("session {}: the result is written but the report is not: {}", id, e.what());
    }
  }
  const SolveReport& report = *outcome.report;
  const std::vector<double> achieved = achievedSigma(report);
  board_.update([&](SessionStatus& s) { s.achieved_sigma_deg = achieved; });
  board_.emit(ResultEvent{id, report, achieved, report_error});
  finish(SessionState::kDone,
         report_error.empty()
             ? ""
             : "result.json is written, but the report (summary.txt, report.html) is not: " +
                   report_error + "; `zerocal report " + store_.sessionDir(id) +
                   "` writes it once there is room");
}

}  // namespace zerocal::service
