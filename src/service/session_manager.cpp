#include "zerocal/service/session_manager.h"

#include <cmath>

#include "zerocal/daemon/logging.h"
#include "zerocal/results/placements.h"
#include "zerocal/service/cell_time.h"

namespace zerocal::service {

const char* stateName(SessionState state) {
  switch (state) {
    case SessionState::kIdle:
      return "idle";
    case SessionState::kConnecting:
      return "connecting";
    case SessionState::kMoving:
      return "moving";
    case SessionState::kServoing:
      return "servoing";
    case SessionState::kRecording:
      return "recording";
    case SessionState::kAwaitingPlacement:
      return "awaiting_placement";
    case SessionState::kSolving:
      return "solving";
    case SessionState::kApplying:
      return "applying";
    case SessionState::kAwaitingCounter:
      return "awaiting_counter";
    case SessionState::kDone:
      return "done";
    case SessionState::kAborted:
      return "aborted";
    case SessionState::kFaulted:
      return "faulted";
    case SessionState::kUnrecovered:
      return "unrecovered";
  }
  return "unknown";
}

bool isActive(SessionState state) {
  return state != SessionState::kIdle && state != SessionState::kDone &&
         state != SessionState::kAborted && state != SessionState::kFaulted &&
         state != SessionState::kUnrecovered;
}

std::vector<record::RobotSummary> SessionControl::robots() const {
  throw Refused("no_record", "this daemon keeps no robot's record");
}

std::vector<record::HistoryEntry> SessionControl::history(const record::RobotId&) const {
  throw Refused("no_record", "this daemon keeps no robot's record");
}

namespace {

double servoZoneUm(const servo::ServoOptions& servo) { return servo.recordedWithinMm() * 1000; }

// The cell as the solves see it: with the configuration's per-pose noise model.
CellKnowledge withNoiseModel(CellKnowledge knowledge, const SessionConfig& session) {
  knowledge.cell.noise = {session.joint_repeatability_deg, session.psd_noise_mm};
  return knowledge;
}

PlannerSettings plannerSettingsOf(const ManagerSettings& settings) {
  PlannerSettings p;
  p.noise_mm = settings.session.noise_mm;
  p.target_mm = settings.target_mm;
  const SolveOptions& solve = settings.run.solve;
  p.tolerances = solve.model;
  p.limit_margin_deg = settings.run.servo.limit_margin_deg;
  p.required_accuracy_deg = solve.required_accuracy_deg;
  p.psd_base_repeatability_mm = settings.session.psd_base_repeatability_mm;
  p.travel_s = settings.travel_s;
  return p;
}

// A check, a restore, or a session given a reference (a verification): measured against it.
bool againstReference(const StartRequest& request) {
  return request.kind == SessionKind::kCheck || request.kind == SessionKind::kRestore ||
         !request.reference.empty();
}

}  // namespace

// Every solve and plan of the daemon counts what its robot model admits (the robot file's
// model_tolerance: a nominal model's tolerances or a calibrated model's covariance).
ManagerSettings withModelOf(ManagerSettings settings, const CellKnowledge& knowledge) {
  settings.run.solve.model = knowledge.cell.robot.tolerance;
  return settings;
}

SessionManager::SessionManager(CellBackend& backend, ManagerSettings settings)
    : settings_(withModelOf(std::move(settings), backend.knowledge())),
      store_(settings_.session.data_dir),
      knowledge_(withNoiseModel(backend.knowledge(), settings_.session)),
      board_(backend.name()),
      planner_(knowledge_, backend, plannerSettingsOf(settings_)),
      connection_(backend, worker_),
      runner_(connection_, board_, worker_, store_, planner_, knowledge_, live_, settings_),
      apply_(connection_, board_, worker_, store_, knowledge_, settings_,
             [this](const std::string& applied, std::string& id) {
               return verificationRun(applied, id);
             }) {
  worker_.setIdleTask(settings_.recovery_retry, [this] { apply_.retryRecovery(); });
}

SessionManager::~SessionManager() {
  board_.abortAll();
  worker_.stop();
  connection_.stopRobot();
  connection_.drop();
}

void SessionManager::setEventSink(EventSink sink) { board_.setEventSink(std::move(sink)); }

std::vector<record::RobotSummary> SessionManager::robots() const {
  if (settings_.record == nullptr) return SessionControl::robots();
  try {
    return settings_.record->robots();
  } catch (const Error& e) {
    throw Refused("record", std::string("the robot's record cannot be read: ") + e.what());
  }
}

std::vector<record::HistoryEntry> SessionManager::history(const record::RobotId& robot) const {
  if (settings_.record == nullptr) return SessionControl::history(robot);
  try {
    return settings_.record->history(robot);
  } catch (const Error& e) {
    throw Refused("record", std::string("the robot's record cannot be read: ") + e.what());
  }
}

SessionStatus SessionManager::status() const {
  SessionStatus s = board_.status();
  {
    // The store is read again only when a session has begun or ended since: the status is asked
    // for several times a second by every terminal watching.
    const std::lock_guard<std::mutex> lock(suggestion_mutex_);
    const std::string key = s.session_id + "/" + stateName(s.state);
    if (key != suggestion_key_ || suggestion_.empty()) {
      const std::string latest = latestReference(store_);
      suggestion_ = suggestedKind(latest);
      suggested_kind_ = latest.empty() ? "reference" : "check";
      suggestion_key_ = key;
    }
    s.suggestion = suggestion_;
    s.suggested_kind = suggested_kind_;
  }
  if (s.state == SessionState::kServoing)
    if (const std::optional<PsdReading> r = live_.load())
      s.live_servo_error_um = r->spot_present ? 1e3 * r->spot.norm() : std::nan("");
  return s;
}

SessionStatus SessionManager::waitIdle() {
  // A run ends (finish) before its task does; a task may start a run only through a claim.
  for (;;) {
    board_.waitInactive();
    worker_.waitIdle();
    if (!board_.activeOrClaimed() && worker_.idle()) return board_.status();
  }
}

std::chrono::steady_clock::duration SessionManager::workerStalledFor() const {
  return worker_.stalledFor();
}

StartRequest SessionManager::defaultRequest() const {
  StartRequest r;
  r.plan = settings_.session.plan;
  r.poses = settings_.session.poses;
  r.plan_file = settings_.session.plan_file;
  r.target_mm = settings_.target_mm;
  r.noise_mm = settings_.session.noise_mm;
  r.placements = settings_.session.placements;
  return r;
}

Plan SessionManager::preview(const StartRequest& request) const {
  std::string model_from;
  Plan plan = againstReference(request) ? planner_.preview(request)
                                        : planCalibration(request, false, model_from).plan;
  predictCellTime(plan, cellTimePerPose(store_));
  return plan;
}

PlannedSession SessionManager::planCalibration(const StartRequest& request, bool checked,
                                               std::string& model_from) const {
  const auto planWith = [&](const Robot* model) {
    if (checked) return planner_.plan(request, model);
    PlannedSession p;
    p.plan = planner_.preview(request, model);
    return p;
  };
  model_from.clear();
  if (request.kind != SessionKind::kCalibration || request.placements > 1) return planWith(nullptr);
  const std::string latest = latestCalibratedModel(store_);
  if (latest.empty()) return planWith(nullptr);
  const CalibratedModel model = loadCalibratedModel(store_, latest);
  PlannedSession planned = planWith(&model.robot);
  if (placementCount(planned.plan.poses) > 1) return planWith(nullptr);  // a plan file's
  model_from = latest;
  planned.plan.description += "; solved with the calibrated model of session " + latest;
  return planned;
}

SessionManager::NewSession SessionManager::createSession(const StartRequest& request) {
  SessionFile draft;
  PlannedSession planned;
  if (againstReference(request)) {
    draft.reference = request.reference.empty() ? latestReference(store_) : request.reference;
    if (draft.reference.empty())
      throw Refused("no_reference",
                    std::string("a ") + sessionKindName(request.kind) +
                        " compares with the robot's reference, and " + store_.dataDir() +
                        " holds none: take one with `zerocal start --kind reference` while the "
                        "robot is known good (or `--kind calibrate --placements 3` for its "
                        "absolute zeros)");
    planned = planner_.planChange(request, request.verifies == draft.reference
                                               ? loadAppliedCalibration(store_, draft.reference)
                                               : loadReference(store_, draft.reference));
    draft.reference_poses = planned.reference_poses;
  } else {
    planned = planCalibration(request, true, draft.model_from);
  }
  predictCellTime(planned.plan, cellTimePerPose(store_));
  const Plan& plan = planned.plan;
  NewSession n;
  n.run.plan = planned.run;
  n.run.found_before = request.found_before;
  draft.kind = request.kind;

  draft.plan = plan;
  draft.target_mm = planned.run.target;
  draft.noise_mm = planned.run.noise_mm;
  draft.placement_centres_mm = planned.run.centres;
  draft.config = settings_.config_snapshot;
  if (!request.verifies.empty()) {
    draft.kind = SessionKind::kVerification;
    draft.verifies = request.verifies;
  }
  n.run.kind = draft.kind;
  const SessionFile created = store_.create(std::move(draft));
  n.id = n.run.id = created.id;
  makeLogger("session")->info("session {} created in {}: {} ({} poses)", created.id,
                              store_.sessionDir(created.id), plan.description, plan.poses.size());

  SessionStatus s;
  s.state = SessionState::kConnecting;
  s.session_id = created.id;
  s.pose_count = static_cast<int>(plan.poses.size());
  s.servo_zone_um = servoZoneUm(settings_.run.servo);
  s.placement_count =
      planned.run.centres.empty() ? 0 : static_cast<int>(planned.run.centres.size());
  s.placement = s.placement_count > 0 ? 1 : 0;
  s.predicted_sigma_deg.assign(plan.prediction.sigma.begin(),
                               plan.prediction.sigma.begin() + kOffsetCount);
  s.apply = board_.status().apply;  // the latest apply stays in the status
  board_.begin(s);
  live_.clear();
  board_.emit(PlanEvent{created.id, s.pose_count, plan.description, s.predicted_sigma_deg});
  board_.announce();
  return n;
}

std::string SessionManager::start(const StartRequest& request) {
  const SessionBoard::Claim claim(board_);
  NewSession n = createSession(request);
  worker_.post([this, run = n.run](bool cancelled) {
    if (cancelled)
      return runner_.finish(SessionState::kAborted, "the daemon stopped before it began");
    runner_.run(run);
  });
  return n.id;
}

std::string SessionManager::resume(const ResumeRequest& request) {
  const SessionBoard::Claim claim(board_);

  std::string id = request.session;
  if (id.empty()) {
    const std::vector<SessionInfo> open = store_.unfinished();
    if (open.empty()) throw Refused("not_found", "no unfinished session to resume");
    id = open.back().id;
  }
  checkSessionId(id);
  std::optional<SessionInfo> info;
  for (const SessionInfo& s : store_.list())
    if (s.id == id) info = s;
  if (!info) throw Refused("not_found", "no session " + id + " in " + settings_.session.data_dir);
  if (info->finished) throw Refused("finished", "session " + id + " is finished: see its result");
  if (info->kind == SessionKind::kVerification)
    throw Refused("verification",
                  "session " + id + " is the verification of session " + info->verifies +
                      "'s apply: it is never resumed as a calibration (measure again with "
                      "`zerocal verify`)" +
                      (info->closed.empty() ? "" : "; " + info->closed));
  if (!info->closed.empty())
    throw Refused("finished", "session " + id + " was closed: " + info->closed);
  if (!info->damaged.empty())
    throw Refused("damaged", "session " + id + " cannot be resumed, its journal is damaged: " +
                                 info->damaged + " (the files are left as they are)");

  SessionFile session;
  try {
    session = store_.readSession(id);
  } catch (const Error& e) {
    throw Refused("bad_session", "session " + id + " cannot be resumed: its session.json " +
                                     "lacks the plan's poses, target_mm or noise_mm (" + e.what() +
                                     ")");
  }
  const RunPlan plan = planner_.runPlanOf(id, session);
  planner_.checkPlaceable(plan);
  std::vector<PoseRecord> records;
  try {
    records = readJournal(store_.journalPath(id)).records;
  } catch (const JournalError& e) {
    throw Refused("damaged", "session " + id + " cannot be resumed, its journal is damaged: " +
                                 e.what() + " (the files are left as they are)");
  }
  const int skip_index =
      planner_.checkResume(id, plan, records, info->recorded_poses, request.skip_pose);
  // Why the pose is given up, for the journal: the fault that stopped the session, when known.
  std::string skip_reason;
  if (skip_index >= 0) {
    const SessionStatus last = board_.status();
    skip_reason = "skipped on request when the session was resumed";
    if (last.session_id == id && last.state == SessionState::kFaulted)
      skip_reason += ", after: " + last.message;
  }
  makeLogger("session")->info("resuming session {}: {} of {} poses recorded", id,
                              info->recorded_poses, plan.poses.size());
  {
    SessionStatus s;
    s.state = SessionState::kConnecting;
    s.session_id = id;
    s.pose_count = static_cast<int>(plan.poses.size());
    s.servo_zone_um = servoZoneUm(settings_.run.servo);
    s.recorded = info->recorded_poses;
    s.resumed_from = info->recorded_poses;
    s.placement_count = plan.centres.empty() ? 0 : static_cast<int>(plan.centres.size());
    s.apply = board_.status().apply;
    // NaN where a hand-edited session.json predicts nothing.
    s.predicted_sigma_deg.assign(session.plan.prediction.sigma.begin(),
                                 session.plan.prediction.sigma.begin() + kOffsetCount);
    board_.begin(s);
  }
  live_.clear();
  board_.announce();
  RunRequest run;
  run.id = id;
  run.kind = session.kind;
  run.plan = plan;
  run.skip_index = skip_index;
  run.skip_reason = skip_reason;
  worker_.post([this, run](bool cancelled) {
    if (cancelled)
      return runner_.finish(SessionState::kAborted, "the daemon stopped before it resumed");
    runner_.run(run);
  });
  return id;
}

std::string SessionManager::continueSession(const ContinueRequest& request) {
  // An apply waiting for the technician at the FlexPendant: its worker goes on.
  if (board_.status().state == SessionState::kAwaitingCounter) {
    if (request.centre_mm)
      throw Refused("bad_request",
                    "centre_mm is for a PSD placement; the apply waits for a revolution counter");
    if (board_.goAhead()) {
      makeLogger("session")->info("apply of session {}: the technician continued",
                                  board_.status().session_id);
      return board_.status().session_id;
    }
  }
  if (request.centre_mm) {
    try {
      checkPlanInput(*request.centre_mm, settings_.session.noise_mm);
    } catch (const InputError& e) {
      throw Refused("bad_request", std::string("centre_mm: ") + e.what());
    }
  }
  const SessionStatus s = board_.leaveWaiting();  // from here on the session is ours to go on
  const std::string& id = s.session_id;
  RunRequest run;
  run.id = id;
  try {
    const SessionFile session = store_.readSession(id);
    run.kind = session.kind;
    run.plan = planner_.runPlanOf(id, session);
    if (s.placement < 2 || s.placement > static_cast<int>(run.plan.centres.size()))
      throw Error("its plan has no placement " + std::to_string(s.placement));
  } catch (const Error& e) {
    // Its session.json changed on disk since it was read at the start: nothing moves.
    board_.finish(SessionState::kFaulted, std::string("cannot go on: ") + e.what());
    throw Refused("bad_session", "session " + id + " cannot go on: " + e.what());
  }
  const Eigen::Vector3d centre = request.centre_mm.value_or(run.plan.centres[s.placement - 1]);
  run.place_next = centre;
  makeLogger("session")->info("session {}: the PSD is at placement {} of {}, taught at {}", id,
                              s.placement, run.plan.centres.size(), centreText(centre));
  live_.clear();
  worker_.post([this, run](bool cancelled) {
    if (cancelled)
      return runner_.finish(SessionState::kAborted, "the daemon stopped before it went on");
    runner_.run(run);
  });
  return id;
}

bool SessionManager::abort() {
  // A waiting session has no worker to stop: it ends here.
  if (board_.abortWaiting()) {
    makeLogger("session")->warn("session {} aborted while waiting for a PSD placement",
                                board_.status().session_id);
    return true;
  }
  if (!board_.requestAbort()) return false;
  const SessionStatus s = board_.status();
  if (isActive(s.state))
    makeLogger("session")->warn("abort requested for session {} ({})", s.session_id,
                                stateName(s.state));
  else
    makeLogger("session")->warn("abort requested while a session is being started");
  return true;
}

std::vector<SessionInfo> SessionManager::sessions() const { return store_.list(); }

ResultFile SessionManager::result(const std::string& requested) const {
  return finishedResult(store_, requested);
}

std::optional<apply::ApplyRecord> SessionManager::lastApply(const std::string& id) const {
  checkSessionId(id);
  return apply::lastApplyRecord(apply::ApplyJournal(store_.sessionDir(id) + "/apply.jsonl"));
}

void SessionManager::readPsd(ReadingDone done) {
  // The board belongs to a running session: report what it last read. A session waiting for the
  // PSD to be moved reads nothing meanwhile, so a reading is taken now (the technician placing
  // the detector may want one).
  if (board_.activeOrClaimed() && board_.status().state != SessionState::kAwaitingPlacement) {
    if (const std::optional<PsdReading> r = live_.load())
      done(LiveReading{*r, true}, "");
    else
      done(std::nullopt, "the session has not read the PSD yet");
    return;
  }
  worker_.post([this, done = std::move(done)](bool cancelled) {
    if (cancelled) return done(std::nullopt, "the daemon is stopping");
    try {
      const PsdReading r = connection_.connect().psd().read();
      done(LiveReading{r, false}, "");
    } catch (const std::exception& e) {
      connection_.drop();
      done(std::nullopt, std::string("cannot read the PSD: ") + e.what());
    }
  });
}

std::string SessionManager::apply(const ApplyRequest& request) { return apply_.apply(request); }

std::string SessionManager::verify(const VerifyRequest& request) { return apply_.verify(request); }

std::string SessionManager::acknowledge(const AcknowledgeRequest& request) {
  return apply_.acknowledge(request);
}

int SessionManager::recoverInterruptedApplies() { return apply_.recoverInterruptedApplies(); }

ResultFile SessionManager::verificationRun(const std::string& applied, std::string& id) {
  // Measured against what the apply came from: a restore's reference (the zeros should be the
  // reference's again), a calibration's own poses at its last PSD placement, where the detector
  // stands (the zeros should have moved by what was written). Either way the link errors cancel,
  // so that a right apply passes at the PSD where it is (docs/apply.md).
  StartRequest request = defaultRequest();
  request.placements = 1;  // a verification runs unattended: the PSD stays where it is
  request.verifies = applied;
  request.kind = SessionKind::kVerification;
  const std::string reference = store_.readSession(applied).reference;
  request.reference = reference.empty() ? applied : reference;
  // The spot predicted from the calibration's laser line and its last placement's centre.
  if (reference.empty())
    request.found_before = loadAppliedCalibration(store_, applied).fit.estimate;
  const NewSession n = createSession(request);
  id = n.id;
  runner_.run(n.run);
  const SessionStatus end = board_.status();
  if (end.state != SessionState::kDone)
    throw Error("verification session " + n.id + " " + stateName(end.state) + ": " + end.message);
  const ResultFile r = store_.readResult(n.id);
  for (int k = 0; k < 4; ++k) {
    const ParameterEstimate& p = r.report.parameters.at(k);
    if (!p.identifiable || !std::isfinite(p.value) || !std::isfinite(p.sigma))
      throw Error("verification session " + n.id + " did not determine delta" +
                  std::to_string(k + 2));
  }
  return r;
}

}  // namespace zerocal::service
