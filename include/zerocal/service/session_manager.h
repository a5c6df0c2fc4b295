// The daemon's one session at a time: the SessionControl implementation and the owner of the
// lifecycle (start, resume, continue, abort, status). It wires the parts that do the work:
//
// - RequestPlanner: checks a request and makes its plan; the rule for poses given up.
// - SessionBoard: the state machine, the status, the claim, the events.
// - SessionWorker: the one thread that touches the cell.
// - CellConnection: connecting the cell and identifying the controller.
// - SessionRunner: a session's run by its kind, ending with the result (assembleResult).
// - ApplyCoordinator: the online apply, its verification, the recovery of an interrupted apply.
//
// The session folders are the SessionStore's. The control port (and `zerocald --once`) drive it
// through SessionControl; the cell comes in through CellBackend.
//
// Threads: every SessionControl method may be called from any thread and returns promptly (none
// waits for the robot). The session itself runs on the manager's worker thread; events are
// delivered on that thread, without any lock held.
#pragma once

#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/cell/cell.h"
#include "zerocal/service/apply_coordinator.h"
#include "zerocal/service/cell_connection.h"
#include "zerocal/service/live_reading.h"
#include "zerocal/service/manager_settings.h"
#include "zerocal/service/request_planner.h"
#include "zerocal/service/session_board.h"
#include "zerocal/service/session_control.h"
#include "zerocal/service/session_runner.h"
#include "zerocal/service/session_worker.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

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
  std::optional<apply::ApplyRecord> lastApply(const std::string& id) const override;
  void readPsd(ReadingDone done) override;
  void setEventSink(EventSink sink) override;
  std::vector<record::RobotSummary> robots() const override;
  std::vector<record::HistoryEntry> history(const record::RobotId& robot) const override;

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
  struct NewSession {
    std::string id;
    RunRequest run;
  };
  // Plans `request` (refusing it as start() does), creates its folder, and begins it on the board.
  NewSession createSession(const StartRequest& request);
  // The plan of a calibration (not against a reference), preview() when `checked` is false and
  // RequestPlanner::plan otherwise, and in `model_from` the calibration whose calibrated model it
  // is planned, and will be solved, with: the latest in the store when the plan has one PSD
  // placement (a calibration at several identifies the links itself).
  PlannedSession planCalibration(const StartRequest& request, bool checked,
                                 std::string& model_from) const;
  // Runs the verification of session `applied`'s apply on the worker thread: the change of the
  // zeros since its reference (a restore) or since its own poses at its last PSD placement (a
  // calibration), ApplyCoordinator::VerificationRun.
  ResultFile verificationRun(const std::string& applied, std::string& id);

  ManagerSettings settings_;
  SessionStore store_;
  CellKnowledge knowledge_;
  LiveReadingSlot live_;
  SessionBoard board_;
  RequestPlanner planner_;
  // These three work on the worker thread only.
  CellConnection connection_;
  SessionRunner runner_;
  ApplyCoordinator apply_;
  // The status' suggestion, kept until a session begins or ends (status()).
  mutable std::mutex suggestion_mutex_;
  mutable std::string suggestion_key_, suggestion_, suggested_kind_;
  SessionWorker worker_;  // last member: its thread starts after the others exist
};

}  // namespace zerocal::service
