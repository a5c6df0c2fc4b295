// The seam between the daemon's sessions and whoever drives them (the control port, `zerocald
// --once`, tests): SessionControl and the types it speaks in. SessionManager implements it; the
// control layer serialises these types and needs nothing else of the service.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "zerocal/apply/online_apply.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"
#include "zerocal/cell/psd_reader.h"
#include "zerocal/error.h"
#include "zerocal/record/robot_record.h"
#include "zerocal/service/plan_kind.h"
#include "zerocal/store/journal.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

enum class SessionState {
  kIdle,        // no session has run since the daemon started
  kConnecting,  // to the controller and the board
  kMoving,      // to pose i of N
  kServoing,    // the spot onto the PSD at pose i
  kRecording,   // pose i to the journal
  // Every pose at the PSD's placement is recorded; the technician moves the PSD to the next
  // placement, then continues the session. The robot is at rest; no worker runs the session.
  kAwaitingPlacement,
  kSolving,
  kApplying,  // an online apply or a verification: writing, restarting, judging, rolling back
  // An online apply waits for the technician to update a joint's revolution counter at its
  // synchronisation mark on the FlexPendant (the controller cannot do it remotely), then to
  // continue. The apply's worker waits; an abort rolls the apply back.
  kAwaitingCounter,
  kDone,
  kAborted,
  kFaulted,
  // An online apply was interrupted and its recovery could not bring the controller to a known
  // state (the controller unreachable, or holding values that are neither the apply's backup nor
  // its written ones, or another controller's apply): no session, apply or verification runs
  // until the recovery succeeds (tried again whenever the controller can be reached) or the
  // technician acknowledges the values checked by hand. The message says what to check.
  kUnrecovered,
};
const char* stateName(SessionState state);
// A session in this state has a worker running it.
bool isActive(SessionState state);

// A request refused without harm: busy, not identifiable, unknown session, bad parameters. `code`
// is a short stable word for scripts (docs/protocol.md lists them).
class Refused : public Error {
 public:
  Refused(std::string code, const std::string& message) : Error(message), code_(std::move(code)) {}
  const std::string& code() const { return code_; }

 private:
  std::string code_;
};

struct StartRequest {
  PlanKind plan = PlanKind::kOptimal;
  int poses = 8;
  std::string plan_file;                     // plan: file
  std::optional<Eigen::Vector3d> target_mm;  // nominal PSD centre; default the cell's taught one
  std::optional<double> noise_mm;            // measurement sigma; default session.noise_mm
  // A verification after an apply: the cell as the calibration it verifies found it
  // (CalibrationRun::found_before). Not on the control port: the daemon's own verification.
  std::optional<CalibrationParameters> found_before;
  // PSD placements (1..kMaxDefaultPlacements): with 2 or more, `poses` at each, the first at the
  // target and the others spread around it (defaultPlacements). Not used with plan: file, whose
  // poses carry their placements.
  int placements = 1;
  // A verification's: the session whose apply it verifies (session.json's kind and verifies).
  // Not on the control port.
  std::string verifies;
  // Start even when the plan is predicted not to determine every offset to the required
  // accuracy (session.required_accuracy_deg): a calibration asked for explicitly, whose result
  // will withhold those offsets. Without it such a plan is refused before anything moves.
  bool even_if_not_usable = false;
  // What the session is for (docs/record.md): a calibration, a reference, a check or a restore.
  // A check or a restore is measured against `reference` (a reference session's id), by default
  // the latest usable one in the data folder.
  SessionKind kind = SessionKind::kCalibration;
  std::string reference;
};

// Goes on with the session that waits for the PSD at its next placement.
struct ContinueRequest {
  // The placement's centre as taught (base frame, mm); default: its planned centre.
  std::optional<Eigen::Vector3d> centre_mm;
};

struct ResumeRequest {
  std::string session;  // the latest unfinished session when empty
  // 1-based pose to skip before going on, 0 for none. Only the next pose to measure may be
  // skipped, and only when the plan stays identifiable without it; the skip is journalled.
  int skip_pose = 0;
};

struct SessionStatus {
  SessionState state = SessionState::kIdle;
  std::string backend;     // "sim" or "hardware"
  std::string session_id;  // the current or last session; empty before the first
  int pose = 0;            // 1-based pose being worked on (moving, servoing, recording)
  int pose_count = 0;
  int recorded = 0;      // poses on disk in this session's journal
  int resumed_from = 0;  // poses found in the journal when the run (re)started
  // Why it stopped, when aborted or faulted; what the technician is to do, when awaiting a
  // placement; when done without its report, why the report is missing.
  std::string message;
  // With two or more PSD placements (0 otherwise): the plan's count, and the placement the PSD
  // stands at (1-based).
  int placement_count = 0;
  int placement = 0;
  // While awaiting a placement: its number and its planned centre (base frame, mm).
  int next_placement = 0;
  Eigen::Vector3d next_centre_mm = Eigen::Vector3d::Zero();
  // When faulted at a pose of its own fault (spot never found, say) that the plan can do
  // without: that pose, 1-based, for `resume` with skip_pose. 0 otherwise.
  int skippable_pose = 0;
  double last_servo_error_um = 0;  // at the last recorded pose
  // The servo records a pose once the spot is this close to its aim (servo.tolerance_um, or the
  // zone's radius, which the servo widens where the arm scatters more at the detector): what a
  // servo error is judged against.
  double servo_zone_um = 0;
  // While servoing: the spot's distance from the PSD centre at the latest reading, um (NaN when
  // the spot is off the detector). Read without disturbing the servo; poll it for live display.
  std::optional<double> live_servo_error_um;
  std::vector<double> predicted_sigma_deg;  // delta2..delta5, from the plan (NaN: not identif.)
  std::vector<double> achieved_sigma_deg;   // from the solve, when done
  double cell_time_s = 0;                   // since the run (re)started
  // The latest online apply, verification or recovery of an interrupted apply, in a sentence:
  // what was applied and how it ended. Empty when there was none since the daemon started.
  std::string apply;
  // What to run next, in a sentence: with no usable reference in the data folder, a reference
  // (or an absolute calibration from three placements); with one, a check against it.
  std::string suggestion;
  // The same as the kind of session a terminal offers first: "reference" or "check".
  std::string suggested_kind;
};

// An online apply of a finished session's offsets to the controller (docs/apply.md).
struct ApplyRequest {
  std::string session;   // the latest finished session when empty
  bool confirm = false;  // the technician confirmed writing the robot's calibration
};

// A verification: a short calibration measuring the offsets left now, judged against the last
// apply of `session` (nothing is written or rolled back).
struct VerifyRequest {
  // When empty: the latest session with an online apply (or verification) in its apply.jsonl,
  // else the latest finished one.
  std::string session;
};

// The technician's word that the controller holds the values it should, checked by hand on the
// FlexPendant after an interrupted apply the daemon could not recover: the apply is closed
// (journalled) and sessions may run again.
struct AcknowledgeRequest {
  std::string session;   // the interrupted apply's session; every one when empty
  bool confirm = false;  // the technician confirmed having checked the values
};

// The latest PSD reading seen, for the live `psd` command.
struct LiveReading {
  PsdReading reading;
  bool during_session = false;  // taken by the running session's servo, not on request
};

// What a session tells whoever watches it, as it happens, in the service's own types; the control
// layer alone turns them into protocol lines (docs/protocol.md, "Events"). Pose numbers are
// 1-based, as a technician counts them; a sigma is NaN for an offset that is not identifiable.

// A session was planned and created; it connects next.
struct PlanEvent {
  std::string session;
  int pose_count = 0;
  std::string description;
  std::vector<double> predicted_sigma_deg;  // delta2..delta5
};

// The session changed state, or went on to another pose.
struct StateEvent {
  SessionState state = SessionState::kIdle;
  std::string session;
  int pose = 0;  // being worked on
  int pose_count = 0;
  int recorded = 0;     // journal lines on disk
  std::string message;  // why it stopped, when aborted or faulted
};

// A pose is on disk: measured, or skipped on request.
struct PoseEvent {
  std::string session;
  int pose_count = 0;
  PoseRecord record;  // as journalled
};

// Every pose at the PSD's placement is recorded: the session waits for the PSD to be moved to
// `placement` (of `placement_count`), its centre planned at `centre_mm` (base frame, mm).
struct PlacementEvent {
  std::string session;
  int placement = 0;
  int placement_count = 0;
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();
  std::string message;  // the same, in a sentence for the technician
};

// The solve named plan poses that do not fit: they are measured again next.
struct RemeasureEvent {
  std::string session;
  std::vector<int> poses;
};

// The result is on disk.
struct ResultEvent {
  std::string session;
  SolveReport report;
  std::vector<double> achieved_sigma_deg;  // delta2..delta5
  // Why the session's report (summary.txt, report.html) could not be written; empty when it was.
  std::string report_error;
};

// A step of an online apply or a verification, as the terminal shows it ("written: ...",
// "verifying by measurement").
struct ApplyProgressEvent {
  std::string session;  // whose offsets are applied
  std::string message;
};

enum class ApplyOutcome {
  kVerified,    // applied and verified: the new values stay
  kRolledBack,  // applied, the verification failed (or could not run): the backup is back
  kFailed,      // stopped before or while writing; the message says what the controller holds
  kRecovered,   // an apply interrupted earlier (the daemon stopped) was restored at start
  kPassed,      // a verification on its own: every offset left is within its bound
  kNotPassed,   // a verification on its own: some are not (nothing was changed)
  // An interrupted apply was not recovered: nothing was written; the message gives the values
  // to check on the controller. The daemon refuses sessions until it is recovered or
  // acknowledged.
  kUnrecovered,
  kAcknowledged,  // an interrupted apply closed on the technician's word (acknowledge)
};
const char* applyOutcomeName(ApplyOutcome outcome);

// An apply or a verification ended.
struct ApplyEvent {
  std::string session;  // whose offsets were applied (or verified)
  ApplyOutcome outcome = ApplyOutcome::kFailed;
  std::string message;       // the verdict; for a rollback or a failure, why
  std::string verification;  // the verification session's id, when one ran
  // The controller's cal_offset of joints 1..6 (rad) before and as written (empty when nothing
  // was read or written).
  std::vector<double> before_rad, written_rad;
  // delta2..delta5 left, as the verification measured them (deg; empty when none ran).
  std::vector<double> remaining_deg, remaining_sigma_deg;
};

using SessionEvent = std::variant<PlanEvent, StateEvent, PoseEvent, RemeasureEvent, ResultEvent,
                                  ApplyProgressEvent, ApplyEvent, PlacementEvent>;

// What the control port needs; SessionManager implements it, protocol tests may fake it.
class SessionControl {
 public:
  virtual ~SessionControl() = default;
  virtual SessionStatus status() const = 0;
  // Plans without moving; throws Refused("bad_request", ...) for an invalid request.
  virtual Plan preview(const StartRequest& request) const = 0;
  // Starts a session and returns its id. Throws Refused: "busy" (one session at a time),
  // "bad_request", "not_identifiable" (the plan cannot identify delta2..delta5; nothing moved),
  // "unrecovered" (an interrupted apply is not recovered: start, resume, apply and verify are
  // refused so until it is, with the values to check on the controller).
  virtual std::string start(const StartRequest& request) = 0;
  // Resumes an unfinished session from its journal, skipping its next pose when asked. Throws
  // Refused: "busy", "unrecovered", "not_found", "finished", "damaged", "bad_session",
  // "verification" (a verification session: never resumed), "bad_request" (a pose
  // that is not the next one), "not_identifiable" (the plan would not identify every offset
  // without the pose; nothing skipped, nothing moved).
  virtual std::string resume(const ResumeRequest& request) = 0;
  // Goes on with the session awaiting a PSD placement: journals the placement (its centre as
  // taught), has a simulated cell move its PSD there, and measures its poses. Returns the
  // session's id. Throws Refused: "not_waiting" (no session awaits a placement), "busy" (the
  // daemon is stopping), "bad_request" (a centre not finite or beyond 10 m).
  virtual std::string continueSession(const ContinueRequest& request) = 0;
  // Applies a finished session's offsets to the controller online (backup, write, restart,
  // verify by a short calibration, roll back when wrong; docs/apply.md) and returns the session's
  // id; progress and the outcome come as ApplyProgressEvent and ApplyEvent. Throws Refused:
  // "not_confirmed" (confirm not set), "busy", "unrecovered", "not_found", "not_usable" (the
  // verdict refuses the result, or an offset of joints 2..5 is withheld), "unsupported" (the
  // controller link offers no calibration access), "bad_request".
  virtual std::string apply(const ApplyRequest& request) = 0;
  // Runs a verification of a session's offsets now (a short calibration; nothing is written) and
  // returns the session's id; the verdict comes as an ApplyEvent. Throws Refused: "busy",
  // "unrecovered", "not_found", "not_usable", "bad_request".
  virtual std::string verify(const VerifyRequest& request) = 0;
  // Closes interrupted applies the daemon could not recover, on the technician's word (journalled
  // in each apply.jsonl), and returns the session's id (the latest closed). Throws Refused:
  // "not_confirmed", "not_found" (no interrupted apply, or none of that session), "busy".
  virtual std::string acknowledge(const AcknowledgeRequest& request) = 0;
  // Asks the running session to stop; the robot is stopped. False when nothing runs.
  virtual bool abort() = 0;
  virtual std::vector<SessionInfo> sessions() const = 0;
  // result.json of a finished session (the latest one when `id` is empty). Throws
  // Refused("not_found").
  virtual ResultFile result(const std::string& id) const = 0;
  // The latest online apply or verification of finished session `id` as its apply journal tells
  // it; nullopt when it was never applied (or the journal cannot be read).
  virtual std::optional<apply::ApplyRecord> lastApply(const std::string& id) const {
    (void)id;
    return std::nullopt;
  }
  // One PSD reading: the running session's latest, or one taken now when no session runs (on the
  // worker thread). `done` is called exactly once, from any thread, with the reading or an error.
  using ReadingDone = std::function<void(std::optional<LiveReading>, const std::string& error)>;
  virtual void readPsd(ReadingDone done) = 0;
  // The sink is called on the worker thread, without a lock held, and must not block.
  using EventSink = std::function<void(const SessionEvent& event)>;
  virtual void setEventSink(EventSink sink) = 0;
  // The robot's record (docs/record.md): every robot it knows, and one robot's sessions oldest
  // first with what was written into its controller. Throw Refused: "no_record" (this daemon
  // keeps none), "record" (it cannot be read, with why).
  virtual std::vector<record::RobotSummary> robots() const;
  virtual std::vector<record::HistoryEntry> history(const record::RobotId& robot) const;
};

}  // namespace zerocal::service
