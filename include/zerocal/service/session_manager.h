// The daemon's one calibration session at a time: planning, checking and starting or resuming a
// run, the run itself on the SessionWorker, and its result files. The state machine and status
// are the SessionBoard's; the session folders are the SessionStore's. The control port (and
// `zerocald --once`) drive it through SessionControl; the cell comes in through CellBackend.
//
// Threads: every SessionControl method may be called from any thread and returns promptly (none
// waits for the robot). The session itself runs on the manager's worker thread; events are
// delivered on that thread, without any lock held.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/apply/transmission_check.h"
#include "zerocal/cell/cell.h"
#include "zerocal/daemon/config.h"
#include "zerocal/service/session_board.h"
#include "zerocal/service/session_control.h"
#include "zerocal/service/session_worker.h"
#include "zerocal/session/calibration_run.h"

namespace zerocal::service {

struct ManagerSettings {
  // The configuration's session section: the data folder, what a request leaves out (plan, poses,
  // plan_file, noise_mm: the measurement sigma for plans and solves). Its target_mm is not used
  // here: target_mm below is the default target, set only on a real cell.
  SessionConfig session;
  RunSettings run;
  std::optional<Eigen::Vector3d> target_mm;  // default nominal target; else the backend's
  nlohmann::json config_snapshot;            // written into each session.json
  // What every move costs the controller beyond its motion, when known (the simulated one's
  // model): the result's pose breakdown then shows it per pose, as moves x cost.
  std::optional<MoveOverhead> move_overhead;
  // The controller's time for a move of the robot between two poses (s): a plan's poses are then
  // visited in the order that takes least time (orderForTravel); empty, in the order chosen.
  std::function<double(const Robot& robot, const Joints& from, const Joints& to)> travel_s;
  // Called with a finished session's folder after result.json is written (summary, report).
  std::function<void(const std::string& session_dir)> write_reports;
  // How long the recovery of an interrupted apply waits for a controller that refuses or ignores
  // connections: a daemon killed while the controller restarted on new values comes back first.
  std::chrono::milliseconds controller_restart_timeout{90000};
  // How often an interrupted apply that could not be recovered is tried again while the daemon
  // is otherwise idle (a quiet look at the controller; a visible attempt when it holds
  // something new).
  std::chrono::milliseconds recovery_retry{10000};
  // The online apply measures joints 2..5's transmissions before it writes (docs/apply.md).
  apply::TransmissionCheckOptions transmission_check;
  // No technician to move the PSD (zerocald --once and the experiments on the simulated cell,
  // whose PSD moves itself): a session at several placements goes on to the next one at once, at
  // its planned centre, instead of waiting for a continue.
  bool unattended_placements = false;
};

class SessionManager final : public SessionControl {
 public:
  SessionManager(CellBackend& backend, ManagerSettings settings);
  // Aborts a running session and waits for the worker (the robot stopped, the journal closed).
  ~SessionManager() override;

  SessionStatus status() const override;
  Plan preview(const StartRequest& request) const override;
  std::string start(const StartRequest& request) override;
  std::string resume(const ResumeRequest& request) override;
  std::string continueSession(const ContinueRequest& request) override;
  std::string apply(const ApplyRequest& request) override;
  std::string verify(const VerifyRequest& request) override;
  bool abort() override;
  std::vector<SessionInfo> sessions() const override;
  ResultFile result(const std::string& id) const override;
  void readPsd(ReadingDone done) override;
  void setEventSink(EventSink sink) override;

  // At the daemon's start: finds sessions whose apply journal (apply.jsonl) ends inside an online
  // apply (the daemon was stopped or killed during it) and restores each one's backed-up values
  // on the worker (zerocal::apply::recoverApply), reporting it in the log, the status (`apply`)
  // and an ApplyEvent. Returns how many were found; the restore runs after this returns
  // (waitIdle() waits for it). Never throws: a recovery that fails is logged and in the status.
  int recoverInterruptedApplies();
  std::string acknowledge(const AcknowledgeRequest& request) override;
  // Blocks until no session is active; returns the final status. For --once and shutdown.
  SessionStatus waitIdle();
  // The request the configuration describes (session.plan, poses, plan_file, target).
  StartRequest defaultRequest() const;
  // How long the worker thread (which also runs the servo) has been inside one step of its task
  // without a sign of progress: a phase change, a PSD reading, a recorded pose. Zero while it
  // waits for work. Lock-free, for the watchdog: a worker stuck while holding the mutex shows.
  std::chrono::steady_clock::duration workerStalledFor() const;

 private:
  class LiveSlot;
  class CellCalibration;
  // What a run needs of its session: the plan's poses, the nominal target (placement 1's centre),
  // the measurement sigma, and with several placements each one's planned centre (the first is
  // the target; empty with one placement).
  struct RunPlan {
    std::vector<Pose> poses;
    Eigen::Vector3d target = Eigen::Vector3d::Zero();
    double noise_mm = 0;
    std::vector<Eigen::Vector3d> centres;
  };
  struct NewSession {
    std::string id;
    RunPlan plan;
    std::optional<CalibrationParameters> found_before;  // StartRequest's
  };
  // A session's run plan from its session.json. Throws Refused("bad_session").
  RunPlan runPlanOf(const std::string& id, const SessionFile& session) const;
  // Plans `request` (refusing it as start() does), creates its folder, and begins it on the board.
  NewSession createSession(const StartRequest& request);
  // A finished session's result, checked as an apply needs it: usable, offsets 2..5 given.
  // Throws Refused.
  ResultFile usableResult(const std::string& requested, std::string& id) const;
  // Runs a short calibration (the configured plan around `target`), a verification of session
  // `applied`, on the worker thread and returns its id and result. Throws Error when it does not
  // finish with delta2..delta5.
  ResultFile verificationRun(const std::string& applied, const CalibrationParameters& found,
                             std::string& id);
  void runApply(const std::string& id, const ResultFile& result);
  void runVerify(const std::string& id, const ResultFile& result);
  // The sessions whose folder's apply.jsonl ends inside an online apply, oldest first.
  std::vector<std::string> interruptedApplies() const;
  // Recovers each of `ids` (apply::recoverApply), waiting for a restarting controller first when
  // `wait_for_restart`; what is not recovered blocks the board (unrecovered_).
  void runRecovery(const std::vector<std::string>& ids, bool wait_for_restart);
  // The worker's idle moments while the board is blocked: the recovery tried again when the
  // controller can be reached and holds something new.
  void retryRecovery();
  void runAcknowledge(const std::vector<std::string>& ids);
  // Closes the unfinished verification sessions of `applied`'s apply, saying `how` it ended.
  void closeVerifications(const std::string& applied, const std::string& how);
  // Why the board is blocked: each unrecovered apply and what to check.
  std::string unrecoveredMessage() const;
  // Connects the cell for a recovery, waiting up to controller_restart_timeout while the
  // controller does not serve (a transient LinkError). Throws the last error after that.
  void connectWaitingForRestart();
  void endApply(const ApplyEvent& event, bool ok);
  struct PoseSkip {
    int index = -1;  // 0-based pose to journal as skipped before running; -1: none
    std::string reason;
  };
  // Runs (or resumes) the session's poses and solve. `found_before`: a verification's
  // calibration (CalibrationRun::found_before). With `place_next`, first journals that the PSD
  // stands at the placement the session waits for, taught at that centre (a continue).
  void runSession(const std::string& id, const RunPlan& plan, const PoseSkip& skip,
                  const std::optional<CalibrationParameters>& found_before = std::nullopt,
                  const std::optional<Eigen::Vector3d>& place_next = std::nullopt);
  // Ends the run (the robot stopped unless done) and logs why.
  void finish(SessionState state, const std::string& message);
  void setPhase(SessionState state, int pose);
  Plan makePlan(const StartRequest& request, Eigen::Vector3d& target, double& noise_mm) const;
  // What the session's solve counts beside the noise (its link and sag tolerances).
  ModelTolerances tolerances() const;
  // The one rule for poses given up (a skip asked for at a resume, one offered after a fault):
  // the prediction of what the solve will have once the rest are measured, counting the same
  // tolerances as the solve and the plan's own prediction.
  Prediction predictWithout(const std::vector<Pose>& plan, const std::vector<bool>& skipped,
                            const Eigen::Vector3d& target, double noise_mm) const;

  CellBackend& backend_;
  ManagerSettings settings_;
  SessionStore store_;
  CellKnowledge knowledge_;
  std::unique_ptr<LiveSlot> live_;
  SessionBoard board_;
  std::unique_ptr<ConnectedCell> cell_;  // worker thread only
  // Worker thread only: the interrupted applies not recovered (id -> why), and what the
  // controller held at the last attempt (empty when it could not be reached).
  std::map<std::string, std::string> unrecovered_;
  std::string last_recovery_seen_;
  SessionWorker worker_;  // last member: its thread starts after the others exist
};

}  // namespace zerocal::service
