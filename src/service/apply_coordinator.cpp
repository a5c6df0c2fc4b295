#include "zerocal/service/apply_coordinator.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "zerocal/apply/online_apply.h"
#include "zerocal/daemon/logging.h"
#include "zerocal/service/request_planner.h"
#include "zerocal/service/session_recording.h"

namespace zerocal::service {

namespace {

constexpr double kRadPerDeg = 0.017453292519943295;
constexpr const char* kApplyJournalName = "apply.jsonl";
// Two values written and read back agree to the controller's float32 and 6 digits.
constexpr double kSameCalOffsetRad = 2e-6;

apply::Offsets offsetsOf(const ResultFile& result) {
  apply::Offsets o;
  for (int k = 0; k < 4; ++k)
    o[k] = {result.report.parameters[k].value, result.report.parameters[k].sigma};
  return o;
}

// What remains of the applied session's offsets after its apply, as its verification measured
// it. A restore's verification measures the change since the reference, which a right restore
// made zero; that remainder is the restore's error and the check's, both counted. A
// calibration's verification measures the change since the calibration's own poses, which a
// right apply made the opposite of what was written: the remainder tells whether the write took
// effect as computed (sign, ratio, revolution counter), and has the verification's uncertainty
// alone (the calibration's own error is not measured again there, docs/apply.md).
apply::Offsets remainingAfter(const ResultFile& applied, const ResultFile& verification) {
  apply::Offsets written = offsetsOf(applied), left = offsetsOf(verification);
  const bool against_write = verification.reference != applied.reference;
  for (int k = 0; k < 4; ++k) {
    if (against_write)
      left[k].value_deg += written[k].value_deg;
    else
      left[k].sigma_deg = std::hypot(written[k].sigma_deg, left[k].sigma_deg);
  }
  return left;
}

// Where the PSD must stand for session `s`'s verification, in a sentence for the technician.
std::string whereTheVerificationMeasures(const SessionFile& s) {
  if (!s.reference.empty())
    return "the verification re-measures poses of reference " + s.reference +
           ": the PSD must stand where it stood for the reference";
  const std::size_t placements = s.placement_centres_mm.size();
  if (placements <= 1)
    return "the verification re-measures poses of this calibration: the PSD must stand where it "
           "stood for them";
  return "the verification re-measures poses of this calibration's placement " +
         std::to_string(placements) + ": the PSD must stand where it stood for them (planned " +
         "centre " + centreText(s.placement_centres_mm.back()) +
         " in the robot base frame), not on its base";
}

// Why the result's offsets of joints 2..5 cannot be applied; empty when they can.
std::string unusable(const ResultFile& r) {
  // Only a calibration's offsets and a restore's change are values for the controller.
  if (r.kind == SessionKind::kReference)
    return "it is a reference, what later checks and restores compare with; it writes nothing";
  if (r.kind == SessionKind::kCheck)
    return "it is a check, which writes nothing; a restore against its reference finds the "
           "values that bring the robot back";
  if (r.kind == SessionKind::kVerification)
    return "it is the verification of an apply, which writes nothing";
  if (!r.report.converged) return "its solve did not converge";
  if (r.verdict_recorded && !r.report.verdict.usable) {
    std::string why = "its verdict refuses it";
    for (const std::string& reason : r.report.verdict.reasons) why += ": " + reason;
    return why;
  }
  if (r.report.parameters.size() < 4) return "it holds no offsets";
  for (int k = 0; k < 4; ++k) {
    const ParameterEstimate& p = r.report.parameters[k];
    if (!p.identifiable || !std::isfinite(p.value) || !std::isfinite(p.sigma))
      return "delta" + std::to_string(k + 2) + " is withheld (" +
             (p.reason.empty() ? std::string("not determined") : p.reason) + ")";
  }
  return "";
}

std::vector<double> vec(const std::array<double, 6>& a) { return {a.begin(), a.end()}; }

std::string applyJournalPath(const SessionStore& store, const std::string& id) {
  return store.sessionDir(id) + "/" + kApplyJournalName;
}

}  // namespace

const char* applyOutcomeName(ApplyOutcome outcome) {
  switch (outcome) {
    case ApplyOutcome::kVerified:
      return "verified";
    case ApplyOutcome::kRolledBack:
      return "rolled_back";
    case ApplyOutcome::kFailed:
      return "failed";
    case ApplyOutcome::kRecovered:
      return "recovered";
    case ApplyOutcome::kPassed:
      return "pass";
    case ApplyOutcome::kNotPassed:
      return "fail";
    case ApplyOutcome::kUnrecovered:
      return "unrecovered";
    case ApplyOutcome::kAcknowledged:
      return "acknowledged";
  }
  return "?";
}

// The connected cell's calibration, connecting it first when a failed session dropped it (the
// verification may fault and the rollback still has to reach the controller).
class ApplyCoordinator::CellCalibration final : public ControllerCalibration {
 public:
  CellCalibration(CellConnection& connection, SessionWorker& worker)
      : connection_(connection), worker_(worker) {}
  std::array<double, 6> readCalOffsets() override { return get().readCalOffsets(); }
  void writeCalOffset(int joint, double rad) override { get().writeCalOffset(joint, rad); }
  void restart() override { get().restart(); }
  std::array<double, 6> readMotorAngles() override { return get().readMotorAngles(); }
  bool updateRevolutionCounter(int joint) override { return get().updateRevolutionCounter(joint); }
  // The controller as it names itself (request 98).
  RobotInfo identity() {
    get();
    return connection_.cell().robot().robotInfo();
  }

 private:
  ControllerCalibration& get() {
    worker_.markProgress();
    ControllerCalibration* calibration = connection_.connect().calibration();
    if (calibration == nullptr)
      throw Error("the controller link offers no access to the motor calibration");
    return *calibration;
  }
  CellConnection& connection_;
  SessionWorker& worker_;
};

ApplyCoordinator::ApplyCoordinator(CellConnection& connection, SessionBoard& board,
                                   SessionWorker& worker, SessionStore& store,
                                   const CellKnowledge& knowledge, const ManagerSettings& settings,
                                   VerificationRun verification)
    : connection_(connection),
      board_(board),
      worker_(worker),
      store_(store),
      knowledge_(knowledge),
      settings_(settings),
      verification_(std::move(verification)) {}

ResultFile ApplyCoordinator::usableResult(const std::string& requested, std::string& id) const {
  ResultFile r = finishedResult(store_, requested);  // Refused not_found, bad_request
  id = r.session.empty() ? requested : r.session;
  if (const std::string why = unusable(r); !why.empty())
    throw Refused("not_usable", "session " + id + " cannot be applied: " + why);
  return r;
}

std::string ApplyCoordinator::apply(const ApplyRequest& request) {
  if (!request.confirm)
    throw Refused("not_confirmed",
                  "an online apply writes the robot's calibration and restarts the controller: "
                  "it needs the technician's confirmation (confirm: true)");
  const SessionBoard::Claim claim(board_);
  std::string id;
  const ResultFile result = usableResult(request.session, id);
  const Robot& robot = knowledge_.cell.robot;
  for (int j = 2; j <= 5; ++j)
    if (robot.transmission[j - 1] == 0)
      throw Refused("unsupported", "the robot file gives joint " + std::to_string(j) +
                                       " no transmission: its cal_offset cannot be computed");
  makeLogger("apply")->warn("applying session {} to the controller (confirmed)", id);
  start(id, "applied", "applying", "the apply began; nothing was written",
        [this, id, result] { runApply(id, result); });
  return id;
}

std::string ApplyCoordinator::verify(const VerifyRequest& request) {
  const SessionBoard::Claim claim(board_);
  // By default the session applied last, not the latest finished one (which, after an apply, is
  // its verification).
  std::string requested = request.session;
  if (requested.empty()) {
    const std::vector<SessionInfo> list = store_.list();
    for (auto it = list.rbegin(); it != list.rend() && requested.empty(); ++it)
      if (apply::lastApplyRecord(apply::ApplyJournal(applyJournalPath(store_, it->id))))
        requested = it->id;
  }
  std::string id;
  const ResultFile result = usableResult(requested, id);
  start(id, "verified", "verifying", "the verification began",
        [this, id, result] { runVerify(id, result); });
  return id;
}

void ApplyCoordinator::start(const std::string& id, const std::string& held_as,
                             const std::string& doing, const std::string& not_begun,
                             std::function<void()> run) {
  board_.hold("session " + id + " is being " + held_as);
  SessionStatus s;
  s.state = SessionState::kApplying;
  s.session_id = id;
  s.apply = doing + " session " + id;
  board_.begin(s);
  board_.announce();
  worker_.post([this, id, not_begun, run = std::move(run)](bool cancelled) {
    if (cancelled) {
      ApplyEvent e;
      e.session = id;
      e.message = "the daemon stopped before " + not_begun;
      return endApply(e, false);
    }
    run();
  });
}

void ApplyCoordinator::runApply(const std::string& id, const ResultFile& result) {
  auto log = makeLogger("apply");
  const LoggedSession logged(id);
  if (result.cell) logged.setRobot(result.cell->controller.serial);
  ApplyEvent event;
  event.session = id;
  const auto progress = [&](const std::string& message) {
    worker_.markProgress();
    log->info("session {}: {}", id, message);
    board_.update([&](SessionStatus& s) { s.apply = "applying session " + id + ": " + message; });
    board_.emit(ApplyProgressEvent{id, message});
  };
  try {
    CellCalibration calibration(connection_, worker_);
    const std::array<double, 6> present = calibration.readCalOffsets();
    event.before_rad = vec(present);
    if (result.cal_offset_rad) {
      for (int j = 2; j <= 5; ++j)
        if (std::abs((*result.cal_offset_rad)[j - 1] - present[j - 1]) > kSameCalOffsetRad)
          throw Refused("changed", "the controller's cal_offset of joint " + std::to_string(j) +
                                       " is " + std::to_string(present[j - 1]) +
                                       " rad, the calibration measured against " +
                                       std::to_string((*result.cal_offset_rad)[j - 1]) +
                                       ": calibrate again; nothing was written");
    } else {
      progress(
          "the session did not record the controller's cal_offset values: applying "
          "against the present ones");
    }
    const Robot& robot = knowledge_.cell.robot;
    apply::ApplyJournal journal(applyJournalPath(store_, id));
    // Measured before anything is written: a transmission whose sign or ratio the robot file has
    // wrong would move the zero the wrong way (docs/apply.md, "The transmission measured").
    std::vector<apply::TransmissionMeasurement> measured;
    for (int j = 2; j <= 5; ++j) {
      progress("joint " + std::to_string(j) +
               ": measuring its transmission (a small joint move, read on the motor side, and "
               "back)");
      measured.push_back(apply::measureTransmission(connection_.cell().robot(), calibration, robot,
                                                    j, settings_.transmission_check));
      progress(measured.back().message);
    }
    apply::journalTransmissionCheck(journal, measured);
    std::string disagree;
    for (const apply::TransmissionMeasurement& m : measured)
      if (!m.agrees) disagree += (disagree.empty() ? "" : "; ") + m.message;
    if (!disagree.empty())
      throw Refused("transmission", "the robot file's transmission disagrees with the cell: " +
                                        disagree + "; nothing was written");
    if (!robot.transmission_confirmed)
      progress(
          "the robot file's transmissions are not confirmed, but agree with the cell's "
          "measurement; the verification settles the rest");
    const apply::Offsets before = offsetsOf(result);
    std::array<apply::CalOffsetChange, 4> changes;
    for (int j = 2; j <= 5; ++j) {
      changes[j - 2] = apply::calOffsetChange(j, before[j - 2].value_deg * kRadPerDeg,
                                              robot.transmission[j - 1], present[j - 1]);
      progress(apply::formulaText(changes[j - 2]));
    }
    apply::OnlineApplyOptions options;
    options.required_deg = settings_.session.required_accuracy_deg;
    options.progress = progress;
    options.controller = calibration.identity();
    // A controller that cannot update a revolution counter remotely (an IRC5 over RAPID) has the
    // technician do it on the FlexPendant, the arm at the joint's synchronisation mark; the
    // verification then finds a counter left on its old turn as a whole motor turn.
    options.update_revolution_counter = [&](int joint, double turn_error_deg) {
      if (calibration.updateRevolutionCounter(joint)) return true;
      const std::string off = fmt::format(FMT_STRING("{:+.4f}"), turn_error_deg);
      const std::string message =
          "update joint " + std::to_string(joint) +
          "'s revolution counter: its calibration value crossed the motor's turn, and until the "
          "counter is updated the joint is " +
          off + " deg off. On the FlexPendant, jog joint " + std::to_string(joint) +
          " to its synchronisation mark, update its revolution counter (Calibrate, Update "
          "revolution counters), start the zerocal RAPID module again, then `zerocal continue`; "
          "`zerocal abort` restores the values from before the apply";
      progress(message);
      const bool went_on = board_.awaitTechnician(message, [this] { worker_.markProgress(); });
      progress(went_on ? "joint " + std::to_string(joint) +
                             "'s revolution counter updated by the technician; going on"
                       : "aborted while waiting for joint " + std::to_string(joint) +
                             "'s revolution counter");
      return went_on;
    };
    options.verify = [&]() {
      progress(whereTheVerificationMeasures(store_.readSession(id)));
      std::string vid;
      try {
        const ResultFile v = verification_(id, vid);
        event.verification = vid;
        journal.append({{"step", "verification"}, {"session", vid}});
        return remainingAfter(result, v);
      } catch (...) {
        event.verification = vid;
        throw;
      }
    };
    const auto restore_board = [&] {
      SessionStatus s = board_.status();
      s.state = SessionState::kApplying;
      s.session_id = id;
      s.pose = s.pose_count = s.recorded = 0;
      board_.begin(s);
    };
    apply::OnlineApplyOutcome outcome;
    try {
      outcome = apply::applyOnline(calibration, changes, before, options, journal);
    } catch (...) {
      restore_board();
      throw;
    }
    restore_board();
    event.before_rad = vec(outcome.before_rad);
    event.written_rad = vec(outcome.written_rad);
    if (outcome.after[0].sigma_deg > 0)
      for (const apply::MeasuredOffset& m : outcome.after) {
        event.remaining_deg.push_back(m.value_deg);
        event.remaining_sigma_deg.push_back(m.sigma_deg);
      }
    event.outcome = outcome.state == apply::ApplyState::kVerified ? ApplyOutcome::kVerified
                                                                  : ApplyOutcome::kRolledBack;
    event.message = outcome.message;
  } catch (const std::exception& e) {
    event.outcome = ApplyOutcome::kFailed;
    event.message = e.what();
  }
  // Stopped inside the apply (the link lost while writing or restarting): the controller holds
  // values nobody verified. It is recovered now, by the same rules as at a restart, before
  // anything else may run.
  bool open = false;
  try {
    open = apply::applyInterrupted(apply::ApplyJournal(applyJournalPath(store_, id)));
  } catch (const std::exception&) {
    open = true;
  }
  if (open) {
    board_.emit(event);
    log->error("session {}: {}: recovering the apply", id, event.message);
    return runRecovery({id}, true);
  }
  endApply(event, event.outcome == ApplyOutcome::kVerified);
}

void ApplyCoordinator::runVerify(const std::string& id, const ResultFile& result) {
  const LoggedSession logged(id);
  if (result.cell) logged.setRobot(result.cell->controller.serial);
  ApplyEvent event;
  event.session = id;
  try {
    CellCalibration calibration(connection_, worker_);
    event.before_rad = vec(calibration.readCalOffsets());
    const Robot& robot = knowledge_.cell.robot;
    std::array<apply::CalOffsetChange, 4> changes;
    for (int j = 2; j <= 5; ++j) {
      changes[j - 2].joint = j;
      changes[j - 2].transmission = robot.transmission[j - 1] != 0 ? robot.transmission[j - 1] : 1;
    }
    std::string vid;
    ResultFile v;
    try {
      v = verification_(id, vid);
    } catch (...) {
      event.verification = vid;
      throw;
    }
    event.verification = vid;
    const apply::Offsets after = remainingAfter(result, v);
    for (const apply::MeasuredOffset& m : after) {
      event.remaining_deg.push_back(m.value_deg);
      event.remaining_sigma_deg.push_back(m.sigma_deg);
    }
    const apply::Verdict verdict =
        apply::judge(changes, offsetsOf(result), after, settings_.session.required_accuracy_deg);
    event.outcome = verdict.pass ? ApplyOutcome::kPassed : ApplyOutcome::kNotPassed;
    event.message = verdict.message;
    nlohmann::json offsets = nlohmann::json::array();
    for (const apply::MeasuredOffset& m : after)
      offsets.push_back({{"value_deg", m.value_deg}, {"sigma_deg", m.sigma_deg}});
    apply::ApplyJournal(applyJournalPath(store_, id))
        .append({{"step", "verify"},
                 {"session", vid},
                 {"found_rad", event.before_rad},
                 {"pass", verdict.pass},
                 {"offsets_after", offsets},
                 {"message", verdict.message}});
  } catch (const std::exception& e) {
    event.outcome = ApplyOutcome::kFailed;
    event.message = std::string("the verification did not complete: ") + e.what();
  }
  SessionStatus s = board_.status();
  s.state = SessionState::kApplying;
  s.session_id = id;
  s.pose = s.pose_count = s.recorded = 0;
  board_.begin(s);
  endApply(event, event.outcome == ApplyOutcome::kPassed, false);
}

std::vector<std::string> ApplyCoordinator::interruptedApplies() const {
  auto log = makeLogger("apply");
  std::vector<std::string> ids;
  // By the folder the journal is in: the recovery writes only what that folder's apply backed up
  // (and only into the controller it recorded).
  for (const SessionInfo& info : store_.list()) {
    const std::string path = info.dir + "/" + kApplyJournalName;
    if (!std::filesystem::exists(path)) continue;
    try {
      if (apply::applyInterrupted(apply::ApplyJournal(path))) ids.push_back(info.id);
    } catch (const std::exception& e) {
      log->error("session {}: {} cannot be read: {}", info.id, path, e.what());
    }
  }
  return ids;
}

int ApplyCoordinator::recoverInterruptedApplies() {
  auto log = makeLogger("apply");
  const std::vector<std::string> ids = interruptedApplies();
  if (ids.empty()) return 0;
  try {
    const SessionBoard::Claim claim(board_, SessionBoard::Claim::Purpose::kRecovery);
    board_.hold("an interrupted apply is being recovered");
    SessionStatus s;
    s.state = SessionState::kApplying;
    s.session_id = ids.back();
    s.apply = "recovering an interrupted apply of session " + ids.back();
    board_.begin(s);
    board_.announce();
    for (const std::string& id : ids)
      log->warn(
          "session {}: an online apply was interrupted (the daemon stopped during it); "
          "recovering it before any session runs",
          id);
    worker_.post([this, ids](bool cancelled) {
      if (cancelled) {
        ApplyEvent e;
        e.session = ids.back();
        e.outcome = ApplyOutcome::kUnrecovered;
        e.message = "the daemon stopped before an interrupted apply was recovered";
        return endApply(e, false);
      }
      runRecovery(ids, true);
    });
  } catch (const std::exception& e) {
    log->error("an interrupted apply cannot be recovered now: {}", e.what());
  }
  return static_cast<int>(ids.size());
}

namespace {

// What the controller holds and who it is, to tell whether a recovery tried again would find
// anything new.
std::string controllerFingerprint(const RobotInfo& controller, const std::array<double, 6>& rad) {
  std::string f = controller.robot_type + "*" + controller.serial;
  for (double v : rad) f += " " + std::to_string(std::lround(v / kSameCalOffsetRad));
  return f;
}

}  // namespace

void ApplyCoordinator::runRecovery(const std::vector<std::string>& ids, bool wait_for_restart) {
  auto log = makeLogger("apply");
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::string& id = ids[i];
    ApplyEvent event;
    event.session = id;
    apply::ApplyJournal journal(applyJournalPath(store_, id));
    try {
      if (wait_for_restart)
        connection_.connectWaitingForRestart(settings_.controller_restart_timeout,
                                             board_.abortRequested());
      CellCalibration calibration(connection_, worker_);
      const RobotInfo controller = calibration.identity();
      const apply::Recovery r = apply::recoverApply(calibration, journal, controller);
      event.before_rad = vec(r.found_rad);
      event.message = r.needed() ? r.message : "nothing to recover";
      if (r.resolved()) {
        event.outcome = ApplyOutcome::kRecovered;
        unrecovered_.erase(id);
        closeVerifications(
            id, std::string("recovered (") + apply::recoveryOutcomeName(r.outcome) + ")");
      } else {
        event.outcome = ApplyOutcome::kUnrecovered;
        unrecovered_[id] = r.message;
      }
      last_recovery_seen_ = controllerFingerprint(controller, calibration.readCalOffsets());
    } catch (const std::exception& e) {
      event.outcome = ApplyOutcome::kUnrecovered;
      event.message = std::string("an interrupted apply was not recovered: ") + e.what() +
                      "; nothing was written. The recovery is tried again whenever the "
                      "controller can be reached. " +
                      apply::interruptedApplyValues(journal);
      unrecovered_[id] = event.message;
      last_recovery_seen_.clear();
      connection_.drop();
    }
    if (event.outcome == ApplyOutcome::kUnrecovered)
      log->error("session {}: {}", id, event.message);
    if (i + 1 < ids.size()) {
      recordSession(settings_.record, store_, id);
      board_.emit(event);
      continue;
    }
    endApply(event, event.outcome == ApplyOutcome::kRecovered);
  }
}

void ApplyCoordinator::retryRecovery() {
  if (!board_.blocked() || board_.activeOrClaimed()) return;
  const std::vector<std::string> ids = interruptedApplies();
  if (ids.empty()) return;
  // Quietly first: a controller still out of reach, or holding what it held at the last attempt,
  // changes nothing, and the status stays as it is.
  try {
    CellCalibration calibration(connection_, worker_);
    const std::string seen =
        controllerFingerprint(calibration.identity(), calibration.readCalOffsets());
    if (seen == last_recovery_seen_) return;
  } catch (const std::exception&) {
    connection_.drop();
    return;
  }
  try {
    const SessionBoard::Claim claim(board_, SessionBoard::Claim::Purpose::kRecovery);
    board_.hold("an interrupted apply is being recovered");
    SessionStatus s = board_.status();
    s.state = SessionState::kApplying;
    s.session_id = ids.back();
    s.apply = "recovering an interrupted apply of session " + ids.back() + " (tried again)";
    board_.begin(s);
    board_.announce();
  } catch (const Refused&) {
    return;  // a request came first; the next idle moment tries again
  }
  makeLogger("apply")->warn("the controller can be reached: trying the recovery again");
  runRecovery(ids, false);
}

std::string ApplyCoordinator::acknowledge(const AcknowledgeRequest& request) {
  if (!request.confirm)
    throw Refused("not_confirmed",
                  "acknowledging an interrupted apply says that the controller's MOC MOTOR_CALIB "
                  "cal_offset values were checked by hand (on the FlexPendant) and are the ones "
                  "the robot is to run on: it needs the technician's confirmation (confirm: true)");
  const SessionBoard::Claim claim(board_, SessionBoard::Claim::Purpose::kRecovery);
  std::vector<std::string> ids = interruptedApplies();
  if (!request.session.empty()) {
    const bool open = std::find(ids.begin(), ids.end(), request.session) != ids.end();
    ids.assign(open ? 1 : 0, request.session);
  }
  if (ids.empty())
    throw Refused("not_found", request.session.empty()
                                   ? std::string("no interrupted apply to acknowledge")
                                   : "session " + request.session + " has no interrupted apply");
  board_.hold("an interrupted apply is being acknowledged");
  SessionStatus s = board_.status();
  s.state = SessionState::kApplying;
  s.session_id = ids.back();
  s.apply = "acknowledging the interrupted apply of session " + ids.back();
  board_.begin(s);
  board_.announce();
  worker_.post([this, ids](bool cancelled) {
    ApplyEvent event;
    event.session = ids.back();
    if (cancelled) {
      event.outcome = ApplyOutcome::kUnrecovered;
      event.message = "the daemon stopped before the acknowledgement was journalled";
      return endApply(event, false);
    }
    runAcknowledge(ids);
  });
  return ids.back();
}

void ApplyCoordinator::runAcknowledge(const std::vector<std::string>& ids) {
  auto log = makeLogger("apply");
  // What the controller holds, for the record, when it can be read; the word is the
  // technician's either way.
  std::optional<std::array<double, 6>> found;
  try {
    found = CellCalibration(connection_, worker_).readCalOffsets();
  } catch (const std::exception& e) {
    connection_.drop();
    log->warn("acknowledging without the controller's values: {}", e.what());
  }
  ApplyEvent event;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::string& id = ids[i];
    event = ApplyEvent{};
    event.session = id;
    if (found) event.before_rad = vec(*found);
    const std::string note =
        "the technician checked the controller's cal_offset values by hand and acknowledged "
        "them" +
        (found ? "; it holds " + apply::valuesText(*found) : std::string());
    try {
      apply::ApplyJournal journal(applyJournalPath(store_, id));
      apply::acknowledgeApply(journal, found, note);
      unrecovered_.erase(id);
      closeVerifications(id, "acknowledged");
      event.outcome = ApplyOutcome::kAcknowledged;
      event.message = note;
      log->warn("session {}: interrupted apply acknowledged: {}", id, note);
    } catch (const std::exception& e) {
      event.outcome = ApplyOutcome::kUnrecovered;
      event.message = std::string("the acknowledgement could not be journalled: ") + e.what();
    }
    if (i + 1 < ids.size()) {
      recordSession(settings_.record, store_, id);
      board_.emit(event);
    }
  }
  endApply(event, event.outcome == ApplyOutcome::kAcknowledged);
}

void ApplyCoordinator::closeVerifications(const std::string& applied, const std::string& how) {
  for (const SessionInfo& info : store_.list()) {
    if (info.kind != SessionKind::kVerification || info.verifies != applied || info.finished ||
        !info.closed.empty())
      continue;
    const std::string why = "the verification of an apply that was interrupted, and " + how +
                            " since; it is not resumed";
    try {
      store_.close(info.id, why);
      makeLogger("apply")->info("session {} closed: {}", info.id, why);
    } catch (const std::exception& e) {
      makeLogger("apply")->error("session {} cannot be closed: {}", info.id, e.what());
    }
  }
}

std::string ApplyCoordinator::unrecoveredMessage() const {
  std::string m;
  for (const auto& [id, why] : unrecovered_)
    m += (m.empty() ? "" : " | ") + ("session " + id + ": " + why);
  return m +
         ". Sessions, applies and verifications are refused until it is recovered (tried "
         "again whenever the controller can be reached) or, once the values are checked on "
         "the FlexPendant, acknowledged (`zerocal acknowledge --confirm`)";
}

void ApplyCoordinator::endApply(const ApplyEvent& event, bool ok, bool wrote) {
  auto log = makeLogger("apply");
  recordSession(settings_.record, store_, event.session);
  const std::string summary = std::string(applyOutcomeName(event.outcome)) + ": " + event.message;
  if (ok)
    log->info("session {}: {}", event.session, summary);
  else
    log->error("session {}: {}", event.session, summary);
  board_.update([&](SessionStatus& s) {
    s.session_id = event.session;
    s.apply = "session " + event.session + " " + summary;
  });
  board_.emit(event);
  if (settings_.write_reports) {
    // The session's report gains the apply: before / written, the verdict, the warnings.
    try {
      settings_.write_reports(store_.sessionDir(event.session),
                              robotHistory(settings_.record, store_.readResult(event.session)));
    } catch (const std::exception& e) {
      log->error("session {}: the report does not show the apply: {}", event.session, e.what());
    }
  }
  // Never run on values nobody verified: while an interrupted apply is open and not recovered,
  // the board refuses everything but its recovery.
  if (unrecovered_.empty()) {
    board_.unblock();
  } else {
    board_.block(unrecoveredMessage());
    board_.finish(SessionState::kUnrecovered, unrecoveredMessage());
    board_.release();
    return;
  }
  const bool rolled_back_or_failed = event.outcome == ApplyOutcome::kRolledBack ||
                                     event.outcome == ApplyOutcome::kFailed ||
                                     event.outcome == ApplyOutcome::kUnrecovered;
  board_.finish(
      rolled_back_or_failed && wrote ? SessionState::kFaulted : SessionState::kDone,
      rolled_back_or_failed || event.outcome == ApplyOutcome::kNotPassed ? event.message : "");
  board_.release();
}

}  // namespace zerocal::service
