#include "zerocal/service/session_manager.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <regex>

#include "zerocal/calib/format.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/calib/solver.h"
#include "zerocal/cell/link_error.h"
#include "zerocal/daemon/logging.h"
#include "zerocal/io/joint_set.h"

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

// The latest reading of the running session, written by the servo's thread and read by the
// control port's: a sequence lock over atomics, so the writer (inside the servo cycle) never
// blocks, allocates or locks.
class SessionManager::LiveSlot {
 public:
  void store(const PsdReading& r) noexcept {
    seq_.fetch_add(1, std::memory_order_acq_rel);  // odd: writing
    u_.store(r.spot.u_mm, std::memory_order_relaxed);
    v_.store(r.spot.v_mm, std::memory_order_relaxed);
    u_se_.store(r.se.u_mm, std::memory_order_relaxed);
    v_se_.store(r.se.v_mm, std::memory_order_relaxed);
    sum_.store(r.sum_v, std::memory_order_relaxed);
    time_.store(r.time_s, std::memory_order_relaxed);
    flags_.store((r.spot_present ? 1 : 0) | (r.in_valid_zone ? 2 : 0), std::memory_order_relaxed);
    seq_.fetch_add(1, std::memory_order_release);
  }
  std::optional<PsdReading> load() const noexcept {
    for (;;) {
      const unsigned before = seq_.load(std::memory_order_acquire);
      if (before == 0) return std::nullopt;
      if (before & 1u) continue;
      PsdReading r;
      r.spot.u_mm = u_.load(std::memory_order_relaxed);
      r.spot.v_mm = v_.load(std::memory_order_relaxed);
      r.se.u_mm = u_se_.load(std::memory_order_relaxed);
      r.se.v_mm = v_se_.load(std::memory_order_relaxed);
      r.sum_v = sum_.load(std::memory_order_relaxed);
      r.time_s = time_.load(std::memory_order_relaxed);
      const int flags = flags_.load(std::memory_order_relaxed);
      r.spot_present = flags & 1;
      r.in_valid_zone = flags & 2;
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == before) return r;
    }
  }
  void clear() noexcept { seq_.store(0, std::memory_order_release); }

 private:
  std::atomic<unsigned> seq_{0};
  std::atomic<double> u_{0}, v_{0}, u_se_{0}, v_se_{0}, sum_{0}, time_{0};
  std::atomic<int> flags_{0};
};

namespace {

// A verification's poses, those where a joint offset moves the spot least first: the shortest
// beam, most nearly square to the PSD (the spot moves by range / cos(incidence) per radian). Its
// spot prediction starts from the calibration, so the first pose's search is centred on where
// the spot would be if the apply was right; if it was not (a wrong transmission doubles an
// offset of up to a degree), this is the pose whose spot is still within the search, and each
// pose found teaches the prediction the next one.
void leastSensitiveFirst(std::vector<Pose>& poses, const CellModel& cell,
                         const CalibrationParameters& found) {
  const Eigen::Vector3d normal = cell.psd_rotation.col(2);
  const auto spread = [&](const Pose& pose) {
    const Line beam = laserLine(cell, pose.q_deg, found);
    const double range = (found.target_mm - beam.point).dot(beam.direction);
    return std::abs(range / normal.dot(beam.direction));
  };
  std::stable_sort(poses.begin(), poses.end(),
                   [&](const Pose& a, const Pose& b) { return spread(a) < spread(b); });
}

// A simulated session's whole world, beside its result (docs/simulated-cell.md).
constexpr const char* kTruthWorldFile = "truth-world.yaml";

// The run's PSD reader, passing each reading on to the live slot, and its time to the watchdog's
// progress mark (an atomic store: nothing that allocates or locks in the servo cycle).
template <class Slot>
class ObservedReader final : public PsdReader {
 public:
  ObservedReader(PsdReader& inner, Slot& slot, SessionWorker& worker)
      : inner_(inner), slot_(slot), worker_(worker) {}
  PsdReading read() override {
    const PsdReading r = inner_.read();
    slot_.store(r);
    worker_.markProgress();
    return r;
  }

 private:
  PsdReader& inner_;
  Slot& slot_;
  SessionWorker& worker_;
};

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

// Session ids are UTC timestamps with an optional clash suffix; anything else (a path, "..") is
// refused before it reaches the file system.
void checkId(const std::string& id) {
  static const std::regex kId("[0-9]{8}T[0-9]{6}Z(-[0-9]{3})?");
  if (!std::regex_match(id, kId))
    throw Refused("bad_request", "'" + id + "' is not a session id (like 20261122T050102Z)");
}

// Throws InputError.
void checkPlanInput(const Eigen::Vector3d& target, double noise_mm) {
  if (!(noise_mm > 0) || !std::isfinite(noise_mm))
    throw InputError("noise_mm must be a positive number of millimetres");
  // No robot cell is larger than this: a target beyond it is a typing error (or 1e308).
  constexpr double kFarthestTargetMm = 1e4;
  if (!target.allFinite() || target.norm() > kFarthestTargetMm)
    throw InputError("target_mm must be three finite numbers within 10 m of the robot's base");
}

// The rule that holds for every plan, whatever its source: nothing moves unless the plan
// identifies delta2..delta5.
void refuseUnlessIdentifiable(const Prediction& prediction) {
  std::string refusal;
  for (int k = 0; k < kOffsetCount; ++k)
    if (!prediction.identifiable[k])
      refusal +=
          std::string(refusal.empty() ? "" : "; ") + unknownName(k) + ": " + prediction.reason[k];
  if (!refusal.empty())
    throw Refused("not_identifiable",
                  "the plan cannot identify every offset, nothing moved: " + refusal);
}

// The servo and the controller keep limit_margin_deg from every joint limit and fault a move into
// it, which a plan would find only once the robot got there: every pose is checked before
// anything moves.
void refuseOutsideLimits(const Robot& robot, const std::vector<Pose>& poses, double margin_deg,
                         const std::string& what) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const std::string v = robot.limitViolation(poses[i].q_deg, margin_deg);
    if (v.empty()) continue;
    const int line = poses[i].source_line;
    throw Refused("out_of_limits",
                  fmt::format("{}pose {}{}: {} of {}; nothing moved", what, i + 1,
                              line ? fmt::format(" (line {})", line) : "", v, robot.name));
  }
}

// The plan's poses less those skipped: what the solve will have when the rest are measured.
std::vector<Pose> posesKept(const std::vector<Pose>& plan, const std::vector<bool>& skipped) {
  std::vector<Pose> kept;
  for (std::size_t i = 0; i < plan.size(); ++i)
    if (i >= skipped.size() || !skipped[i]) kept.push_back(plan[i]);
  return kept;
}

// Where the technician is to put the PSD for each placement of the poses: the target for the
// first, for the others the point their nominal lines cross (a planned placement's centre, which
// its poses aim at). Empty with one placement.
std::vector<Eigen::Vector3d> plannedCentres(const CellModel& cell, const std::vector<Pose>& poses,
                                            const Eigen::Vector3d& target) {
  const PlacementLayout layout(poses, cell.robot, false);
  if (layout.count() < 2) return {};
  CalibrationParameters nominal;
  nominal.target_mm = target;
  std::vector<Eigen::Vector3d> centres = placementTargets(cell, poses, layout, nominal, false);
  centres.front() = target;
  return centres;
}

// Several placements need a cell whose PSD can be moved between them.
void refuseUnlessPlaceable(const CellBackend& backend) {
  const std::string why = backend.placementsRefusal();
  if (!why.empty()) throw Refused("unsupported", why);
}

std::string centreText(const Eigen::Vector3d& c) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.1f, %.1f, %.1f) mm", c.x(), c.y(), c.z());
  return text;
}

std::vector<bool> skippedPoses(const std::vector<PoseRecord>& records, std::size_t plan_size) {
  std::vector<bool> skipped(plan_size, false);
  for (const PoseRecord& r : records)
    if (!r.measured() && r.index >= 0 && static_cast<std::size_t>(r.index) < plan_size)
      skipped[r.index] = true;
  return skipped;
}

}  // namespace

SessionManager::SessionManager(CellBackend& backend, ManagerSettings settings)
    : backend_(backend),
      settings_(std::move(settings)),
      store_(settings_.session.data_dir),
      knowledge_(backend.knowledge()),
      live_(std::make_unique<LiveSlot>()),
      board_(backend.name()) {
  worker_.setIdleTask(settings_.recovery_retry, [this] { retryRecovery(); });
}

SessionManager::~SessionManager() {
  board_.abortAll();
  worker_.stop();
  if (cell_) cell_->stopRobot();
  cell_.reset();
}

void SessionManager::setEventSink(EventSink sink) { board_.setEventSink(std::move(sink)); }

SessionStatus SessionManager::status() const {
  SessionStatus s = board_.status();
  if (s.state == SessionState::kServoing)
    if (const std::optional<PsdReading> r = live_->load())
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

ModelTolerances SessionManager::tolerances() const {
  const SolveOptions& s = settings_.run.solve;
  return {s.model_length_mm, s.model_angle_deg, s.model_sag_deg};
}

Prediction SessionManager::predictWithout(const std::vector<Pose>& plan,
                                          const std::vector<bool>& skipped,
                                          const Eigen::Vector3d& target, double noise_mm) const {
  CalibrationParameters nominal;
  nominal.target_mm = target;
  return predictUncertainty(knowledge_.cell, posesKept(plan, skipped), nominal, noise_mm,
                            tolerances());
}

Plan SessionManager::makePlan(const StartRequest& request, Eigen::Vector3d& target,
                              double& noise_mm) const {
  target = request.target_mm.value_or(settings_.target_mm.value_or(knowledge_.taught_centre_mm));
  noise_mm = request.noise_mm.value_or(settings_.session.noise_mm);
  try {
    checkPlanInput(target, noise_mm);
    if (request.plan == PlanKind::kFile) {
      if (request.plan_file.empty())
        throw Refused("bad_request", "plan 'file' needs a plan_file (a joint-set file)");
      Plan plan;
      plan.poses = readJointSet(request.plan_file);
      checkPoses(knowledge_.cell, plan.poses);  // the same minimum and limits as a solve
      refuseOutsideLimits(knowledge_.cell.robot, plan.poses, settings_.run.servo.limit_margin_deg,
                          "plan file " + request.plan_file + ": ");
      plan.description = "plan file " + request.plan_file;
      CalibrationParameters nominal;
      nominal.target_mm = target;
      plan.prediction =
          predictUncertainty(knowledge_.cell, plan.poses, nominal, noise_mm, tolerances());
      return plan;
    }
    PlanOptions options;
    options.pattern = patternOf(request.plan);
    options.poses = request.poses;
    options.noise_mm = noise_mm;
    options.psd_normal = knowledge_.cell.psd_rotation.col(2);
    options.tolerances = tolerances();  // the prediction the technician sees is the solve's
    if (settings_.travel_s)
      options.travel_s = [this](const Joints& from, const Joints& to) {
        return settings_.travel_s(knowledge_.cell.robot, from, to);
      };
    if (request.placements < 1 || request.placements > kMaxDefaultPlacements)
      throw InputError("placements: " + std::to_string(request.placements) + " is outside 1.." +
                       std::to_string(kMaxDefaultPlacements));
    if (request.placements > 1) {
      refuseUnlessPlaceable(backend_);
      options.more_placements = defaultPlacements(target, request.placements);
    }
    Plan plan = planPoses(knowledge_.cell, target, options);
    if (request.found_before)
      leastSensitiveFirst(plan.poses, knowledge_.cell, *request.found_before);
    return plan;
  } catch (const InputError& e) {
    throw Refused("bad_request", e.what());
  }
}

Plan SessionManager::preview(const StartRequest& request) const {
  Eigen::Vector3d target;
  double noise_mm = 0;
  return makePlan(request, target, noise_mm);
}

SessionManager::NewSession SessionManager::createSession(const StartRequest& request) {
  NewSession n;
  const Plan plan = makePlan(request, n.plan.target, n.plan.noise_mm);
  refuseUnlessIdentifiable(plan.prediction);
  n.plan.poses = plan.poses;
  n.plan.centres = plannedCentres(knowledge_.cell, plan.poses, n.plan.target);
  if (!n.plan.centres.empty()) refuseUnlessPlaceable(backend_);  // a plan file's placements
  n.found_before = request.found_before;

  SessionFile draft;
  draft.plan = plan;
  draft.target_mm = n.plan.target;
  draft.noise_mm = n.plan.noise_mm;
  draft.placement_centres_mm = n.plan.centres;
  draft.config = settings_.config_snapshot;
  if (!request.verifies.empty()) {
    draft.kind = SessionKind::kVerification;
    draft.verifies = request.verifies;
  }
  const SessionFile created = store_.create(std::move(draft));
  n.id = created.id;
  makeLogger("session")->info("session {} created in {}: {} ({} poses)", created.id,
                              store_.sessionDir(created.id), plan.description, plan.poses.size());

  SessionStatus s;
  s.state = SessionState::kConnecting;
  s.session_id = created.id;
  s.pose_count = static_cast<int>(plan.poses.size());
  s.placement_count = n.plan.centres.empty() ? 0 : static_cast<int>(n.plan.centres.size());
  s.placement = s.placement_count > 0 ? 1 : 0;
  s.predicted_sigma_deg.assign(plan.prediction.sigma.begin(),
                               plan.prediction.sigma.begin() + kOffsetCount);
  s.apply = board_.status().apply;  // the latest apply stays in the status
  board_.begin(s);
  live_->clear();
  board_.emit(PlanEvent{created.id, s.pose_count, plan.description, s.predicted_sigma_deg});
  board_.announce();
  return n;
}

std::string SessionManager::start(const StartRequest& request) {
  const SessionBoard::Claim claim(board_);
  NewSession n = createSession(request);
  worker_.post([this, n](bool cancelled) {
    if (cancelled) return finish(SessionState::kAborted, "the daemon stopped before it began");
    runSession(n.id, n.plan, {}, n.found_before);
  });
  return n.id;
}

SessionManager::RunPlan SessionManager::runPlanOf(const std::string& id,
                                                  const SessionFile& session) const {
  RunPlan plan{session.plan.poses, session.target_mm, session.noise_mm,
               session.placement_centres_mm};
  // session.json is a file anyone with access may have edited: what it asks of the robot is
  // checked exactly as a new plan is.
  try {
    checkPlanInput(plan.target, plan.noise_mm);
    checkPoses(knowledge_.cell, plan.poses);
    if (plan.centres.empty())
      plan.centres = plannedCentres(knowledge_.cell, plan.poses, plan.target);
    if (placementCount(plan.poses) > 1 &&
        static_cast<int>(plan.centres.size()) != placementCount(plan.poses))
      throw InputError("its plan has " + std::to_string(placementCount(plan.poses)) +
                       " placements but " + std::to_string(plan.centres.size()) + " centres");
    for (const Eigen::Vector3d& c : plan.centres) checkPlanInput(c, plan.noise_mm);
  } catch (const InputError& e) {
    throw Refused("bad_session", "session " + id + " cannot be resumed: " + e.what());
  }
  refuseOutsideLimits(knowledge_.cell.robot, plan.poses, settings_.run.servo.limit_margin_deg,
                      "session " + id + " cannot be resumed: ");
  return plan;
}

std::string SessionManager::resume(const ResumeRequest& request) {
  const SessionBoard::Claim claim(board_);

  std::string id = request.session;
  if (id.empty()) {
    const std::vector<SessionInfo> open = store_.unfinished();
    if (open.empty()) throw Refused("not_found", "no unfinished session to resume");
    id = open.back().id;
  }
  checkId(id);
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
  const RunPlan plan = runPlanOf(id, session);
  const std::vector<Pose>& poses = plan.poses;
  const Eigen::Vector3d target = plan.target;
  const double noise_mm = plan.noise_mm;
  if (!plan.centres.empty()) refuseUnlessPlaceable(backend_);
  std::vector<bool> skipped;
  try {
    skipped = skippedPoses(readJournal(store_.journalPath(id)).records, poses.size());
  } catch (const JournalError& e) {
    throw Refused("damaged", "session " + id + " cannot be resumed, its journal is damaged: " +
                                 e.what() + " (the files are left as they are)");
  }
  int skip_index = -1;
  if (request.skip_pose != 0) {
    const int next = info->recorded_poses;
    if (next >= static_cast<int>(poses.size()))
      throw Refused("bad_request", "session " + id + " has all " + std::to_string(poses.size()) +
                                       " poses recorded: there is no pose left to skip");
    if (request.skip_pose != next + 1)
      throw Refused("bad_request", "pose " + std::to_string(request.skip_pose) +
                                       " cannot be skipped: only the next pose to measure can, " +
                                       "pose " + std::to_string(next + 1) + " of session " + id);
    skip_index = next;
    skipped[skip_index] = true;
  }
  try {
    refuseUnlessIdentifiable(predictWithout(poses, skipped, target, noise_mm));
  } catch (const Refused& e) {
    if (skip_index < 0) throw;
    throw Refused(e.code(), "without pose " + std::to_string(skip_index + 1) + ", " + e.what() +
                                "; the pose is not skipped");
  }
  // Why the pose is given up, for the journal: the fault that stopped the session, when known.
  std::string skip_reason;
  if (skip_index >= 0) {
    const SessionStatus last = board_.status();
    skip_reason = "skipped on request when the session was resumed";
    if (last.session_id == id && last.state == SessionState::kFaulted)
      skip_reason += ", after: " + last.message;
  }
  makeLogger("session")->info("resuming session {}: {} of {} poses recorded", id,
                              info->recorded_poses, poses.size());
  {
    SessionStatus s;
    s.state = SessionState::kConnecting;
    s.session_id = id;
    s.pose_count = static_cast<int>(poses.size());
    s.recorded = info->recorded_poses;
    s.resumed_from = info->recorded_poses;
    s.placement_count = plan.centres.empty() ? 0 : static_cast<int>(plan.centres.size());
    s.apply = board_.status().apply;
    // NaN where a hand-edited session.json predicts nothing.
    s.predicted_sigma_deg.assign(session.plan.prediction.sigma.begin(),
                                 session.plan.prediction.sigma.begin() + kOffsetCount);
    board_.begin(s);
  }
  live_->clear();
  board_.announce();
  worker_.post([this, id, plan, skip_index, skip_reason](bool cancelled) {
    if (cancelled) return finish(SessionState::kAborted, "the daemon stopped before it resumed");
    runSession(id, plan, {skip_index, skip_reason});
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
  RunPlan plan;
  try {
    plan = runPlanOf(id, store_.readSession(id));
    if (s.placement < 2 || s.placement > static_cast<int>(plan.centres.size()))
      throw Error("its plan has no placement " + std::to_string(s.placement));
  } catch (const Error& e) {
    // Its session.json changed on disk since it was read at the start: nothing moves.
    board_.finish(SessionState::kFaulted, std::string("cannot go on: ") + e.what());
    throw Refused("bad_session", "session " + id + " cannot go on: " + e.what());
  }
  const Eigen::Vector3d centre = request.centre_mm.value_or(plan.centres[s.placement - 1]);
  makeLogger("session")->info("session {}: the PSD is at placement {} of {}, taught at {}", id,
                              s.placement, plan.centres.size(), centreText(centre));
  live_->clear();
  worker_.post([this, id, plan, centre](bool cancelled) {
    if (cancelled) return finish(SessionState::kAborted, "the daemon stopped before it went on");
    runSession(id, plan, {}, std::nullopt, centre);
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

void SessionManager::setPhase(SessionState state, int pose) {
  worker_.markProgress();
  board_.setPhase(state, pose);
}

void SessionManager::finish(SessionState state, const std::string& message) {
  auto log = makeLogger("session");
  if (state != SessionState::kDone && cell_) cell_->stopRobot();
  const std::string id = board_.status().session_id;
  if (state == SessionState::kDone)
    log->info("session {} done", id);
  else
    log->error("session {} {}: {} (every recorded pose is in {})", id, stateName(state), message,
               store_.journalPath(id));
  board_.finish(state, message);
}

void SessionManager::runSession(const std::string& id, const RunPlan& run_plan,
                                const PoseSkip& skip,
                                const std::optional<CalibrationParameters>& found_before,
                                const std::optional<Eigen::Vector3d>& place_next) {
  auto log = makeLogger("session");
  const std::vector<Pose>& plan = run_plan.poses;
  const Eigen::Vector3d& target = run_plan.target;
  const double noise_mm = run_plan.noise_mm;
  // Every placement's planned centre, placement 1's first: the target alone with one.
  const std::vector<Eigen::Vector3d> centres =
      run_plan.centres.empty() ? std::vector<Eigen::Vector3d>{target} : run_plan.centres;
  const int placement_count = static_cast<int>(centres.size());
  if (board_.abortRequested()) return finish(SessionState::kAborted, "aborted before connecting");
  try {
    if (!cell_) {
      setPhase(SessionState::kConnecting, 0);
      log->info("connecting to the {} cell", backend_.name());
      cell_ = backend_.connect();
    }
  } catch (const std::exception& e) {
    return finish(SessionState::kFaulted, std::string("cannot connect to the cell: ") + e.what());
  }
  // Which robot this is, as its controller says: the result names it (and a report of it).
  // The links are kept between sessions; a controller restarted meanwhile (an apply by another
  // client, a power cycle) has dropped them, and this first request is where that shows: both
  // links are made again before anything moves, or the PSD's would read as no light.
  RobotInfo robot;
  try {
    try {
      robot = cell_->robot().robotInfo();
    } catch (const LinkError& e) {
      if (e.kind() != LinkError::Kind::kTransient) throw;
      log->info(
          "session {}: the link to the controller was lost since the last session ({}): "
          "connecting again",
          id, e.what());
      cell_->reconnectRobot();
      robot = cell_->robot().robotInfo();
    }
    log->info("session {}: {} serial {}, controller software {}", id, robot.robot_type,
              robot.serial, robot.software_version);
  } catch (const std::exception& e) {
    log->warn("session {}: the controller did not identify the robot: {}", id, e.what());
  }
  // The motor calibration the offsets are measured against: an apply checks it is still there.
  std::optional<std::array<double, 6>> cal_offset_rad;
  if (ControllerCalibration* calibration = cell_->calibration()) {
    try {
      cal_offset_rad = calibration->readCalOffsets();
    } catch (const std::exception& e) {
      log->warn("session {}: the controller did not report its cal_offset values: {}", id,
                e.what());
    }
  }

  std::optional<RunOutcome> outcome;
  double cell_time_s = 0;
  try {
    Journal journal(store_.journalPath(id));
    if (!journal.dropped().empty())
      log->warn("session {}: {} (the pose will be measured again)", id, journal.dropped());
    RunSettings run_settings = settings_.run;
    run_settings.solve.noise_mm = noise_mm;
    // A dropped controller connection or an unplugged board is recovered by reopening it; the
    // pose in progress (not journalled) is then measured again from its planned move.
    run_settings.reconnect_link = [this] { cell_->reconnectRobot(); };
    run_settings.reopen_sensor = [this] { cell_->reopenPsd(); };
    CalibrationRun run(knowledge_.cell, target, plan, run_settings, journal);
    run.found_before = found_before;
    if (place_next) run.placeNext(*place_next);
    // The cell's PSD where the journal has it: the simulated cell moves its detector there (back
    // to placement 1 for a session of one); on a real cell the technician has, and nothing
    // happens. Again at every placement an unattended run goes on to.
    const auto placed = [&](int placement) {
      cell_->placePsd(placement, centres);
      board_.update([&](SessionStatus& s) { s.placement = placement_count > 1 ? placement : 0; });
    };
    placed(journal.placement());
    const double start_s = cell_->clock().nowS();
    run.on_phase = [this, start_s](int i, RunPhase phase) {
      // The cell's clock is the worker's to read: the status gets its time at each phase.
      const double elapsed_s = cell_->clock().nowS() - start_s;
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
    if (skip.index >= 0) {
      // resume() checked this pose is the next one and the plan identifiable without it.
      run.skipNextPose(skip.reason);
      log->warn("session {}: pose {} skipped ({})", id, skip.index + 1, skip.reason);
    }
    ObservedReader<LiveSlot> reader(cell_->psd(), *live_, worker_);
    outcome = run.run(cell_->robot(), reader, cell_->clock(), board_.abortRequested());
    while (outcome->state == RunState::kAwaitingPlacement && settings_.unattended_placements) {
      const int next = outcome->next_placement;
      log->info("session {}: no technician; the PSD goes on to placement {} at {}", id, next,
                centreText(centres[next - 1]));
      board_.emit(PlacementEvent{id, next, placement_count, centres[next - 1],
                                 "placement " + std::to_string(next) + " of " +
                                     std::to_string(placement_count) + " at its planned centre"});
      run.placeNext(centres[next - 1]);
      placed(next);
      RunOutcome then = run.run(cell_->robot(), reader, cell_->clock(), board_.abortRequested());
      then.resumed_from = outcome->resumed_from;
      then.reconnects += outcome->reconnects;
      then.reopens += outcome->reopens;
      outcome = std::move(then);
    }
    cell_time_s = cell_->clock().nowS() - start_s;
  } catch (const std::exception& e) {
    cell_.reset();
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
      std::vector<bool> skipped = skippedPoses(outcome->records, plan.size());
      skipped[outcome->stopped_at] = true;
      const Prediction without = predictWithout(plan, skipped, target, noise_mm);
      const bool skippable =
          std::all_of(without.identifiable.begin(), without.identifiable.begin() + kOffsetCount,
                      [](bool b) { return b; });
      const std::string pose = std::to_string(outcome->stopped_at + 1);
      if (skippable) {
        message += "; the plan identifies every offset without pose " + pose +
                   ": `zerocal resume " + id + " --skip-pose " + pose + "` skips it";
        board_.update([&](SessionStatus& s) { s.skippable_pose = outcome->stopped_at + 1; });
      } else {
        message += "; without pose " + pose +
                   " the plan would not identify every offset: plan a new session";
      }
    }
    finish(SessionState::kFaulted, message);
    cell_.reset();  // the links may be in any state: the next session connects afresh
    return;
  }

  const SolveReport& report = *outcome->report;
  ResultFile result;
  result.report = report;
  result.session = id;
  result.cell_time_s = cell_time_s;
  result.resumed_from = outcome->resumed_from;
  result.remeasured.emplace();
  for (const int i : outcome->remeasured) result.remeasured->push_back(i + 1);
  result.cell = ResultFile::Cell{robot, knowledge_.psd_map};
  result.cal_offset_rad = cal_offset_rad;
  result.zerocal_version = PROJECT_VERSION;
  result.finished_unix_s = std::chrono::duration_cast<std::chrono::seconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  result.recoveries = ResultFile::Recoveries{outcome->reconnects, outcome->reopens};
  if (const auto truth = cell_->truthDeg()) {
    result.truth.emplace();
    for (int k = 0; k < kOffsetCount; ++k) result.truth->offsets_deg[k] = (*truth)[k];
  }
  if (const auto world = cell_->truthWorldYaml()) {
    try {
      store_.writeFile(id, kTruthWorldFile, *world);
      if (!result.truth) result.truth.emplace();
      result.truth->world_file = kTruthWorldFile;
    } catch (const std::exception& e) {
      return finish(SessionState::kFaulted, std::string("cannot write the truth: ") + e.what());
    }
  }
  result.pose_breakdown.emplace();
  for (const PoseRecord& r : outcome->records) {
    PoseTimes pose;
    pose.pose = r.planIndex() + 1;
    if (!r.measured()) {
      pose.skipped = r.skipped;
    } else {
      pose.servo = r.servo;
      pose.again = r.remeasure_of >= 0;
      if (settings_.move_overhead) {
        // Included in the times above: the planned move and every servo move pay them.
        const double moves = r.servo.moves + 1;
        pose.move_overhead_s = moves * settings_.move_overhead->fixed_s;
        pose.fine_point_settle_s = moves * settings_.move_overhead->settle_s;
      }
    }
    result.pose_breakdown->push_back(pose);
  }
  try {
    store_.writeResult(id, result);
  } catch (const std::exception& e) {
    return finish(SessionState::kFaulted, std::string("cannot write the result: ") + e.what());
  }
  // The session is done with its result on disk whatever happens to the report, but whoever
  // follows it must learn that summary.txt and report.html are missing (a full disk, say).
  std::string report_error;
  if (settings_.write_reports) {
    try {
      settings_.write_reports(store_.sessionDir(id));
    } catch (const std::exception& e) {
      report_error = e.what();
      log->error("session {}: the result is written but the report is not: {}", id, e.what());
    }
  }
  std::vector<double> achieved;
  for (int k = 0; k < kOffsetCount; ++k)
    achieved.push_back(report.parameters[k].identifiable ? report.parameters[k].sigma
                                                         : std::nan(""));
  board_.update([&](SessionStatus& s) { s.achieved_sigma_deg = achieved; });
  board_.emit(ResultEvent{id, report, achieved, report_error});
  finish(SessionState::kDone,
         report_error.empty()
             ? ""
             : "result.json is written, but the report (summary.txt, report.html) is not: " +
                   report_error + "; `zerocal report " + store_.sessionDir(id) +
                   "` writes it once there is room");
}

std::vector<SessionInfo> SessionManager::sessions() const { return store_.list(); }

ResultFile SessionManager::result(const std::string& requested) const {
  std::string id = requested;
  if (id.empty()) {
    for (const SessionInfo& s : store_.list())
      if (s.finished) id = s.id;  // oldest first: the last one is the latest
    if (id.empty()) throw Refused("not_found", "no finished session yet");
  }
  checkId(id);
  if (!std::filesystem::exists(std::filesystem::path(store_.sessionDir(id)) / kResultFileName))
    throw Refused("not_found", "session " + id + " has no result (unknown or unfinished)");
  try {
    return store_.readResult(id);
  } catch (const Error& e) {
    throw Error("the result of session " + id + " cannot be read: " + e.what());
  }
}

void SessionManager::readPsd(ReadingDone done) {
  // The board belongs to a running session: report what it last read. A session waiting for the
  // PSD to be moved reads nothing meanwhile, so a reading is taken now (the technician placing
  // the detector may want one).
  if (board_.activeOrClaimed() && board_.status().state != SessionState::kAwaitingPlacement) {
    if (const std::optional<PsdReading> r = live_->load())
      done(LiveReading{*r, true}, "");
    else
      done(std::nullopt, "the session has not read the PSD yet");
    return;
  }
  worker_.post([this, done = std::move(done)](bool cancelled) {
    if (cancelled) return done(std::nullopt, "the daemon is stopping");
    try {
      if (!cell_) cell_ = backend_.connect();
      const PsdReading r = cell_->psd().read();
      done(LiveReading{r, false}, "");
    } catch (const std::exception& e) {
      cell_.reset();
      done(std::nullopt, std::string("cannot read the PSD: ") + e.what());
    }
  });
}

}  // namespace zerocal::service
