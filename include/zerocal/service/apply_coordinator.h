// The online apply, its verification and the recovery of an interrupted apply (docs/apply.md):
// the engine (zerocal/apply/online_apply.h) driven on the session worker against the connected
// cell's ControllerCalibration. A verification is an ordinary session of the configured plan (its
// own folder, events and result), which the coordinator has run through `VerificationRun`.
//
// The requests (apply, verify, acknowledge) are SessionControl's, checked on the caller's thread
// and run on the worker; what is not recovered blocks the board until it is, or is acknowledged.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "zerocal/service/cell_connection.h"
#include "zerocal/service/manager_settings.h"
#include "zerocal/service/session_board.h"
#include "zerocal/service/session_control.h"
#include "zerocal/service/session_worker.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

class ApplyCoordinator {
 public:
  // Runs the verification of session `applied`'s apply on the worker thread (the change of the
  // zeros since the poses the apply came from: SessionManager::verificationRun), setting `id` to
  // the verification session's id as soon as it exists, and returns its result. Throws Error
  // when it does not finish with delta2..delta5.
  using VerificationRun = std::function<ResultFile(const std::string& applied, std::string& id)>;

  // Every part outlives the coordinator.
  ApplyCoordinator(CellConnection& connection, SessionBoard& board, SessionWorker& worker,
                   SessionStore& store, const CellKnowledge& knowledge,
                   const ManagerSettings& settings, VerificationRun verification);

  // SessionControl's apply, verify and acknowledge (session_control.h says what they throw).
  std::string apply(const ApplyRequest& request);
  std::string verify(const VerifyRequest& request);
  std::string acknowledge(const AcknowledgeRequest& request);
  // SessionManager::recoverInterruptedApplies.
  int recoverInterruptedApplies();
  // The worker's idle moments while the board is blocked: the recovery tried again when the
  // controller can be reached and holds something new. Worker thread.
  void retryRecovery();

 private:
  class CellCalibration;
  // A finished session's result, checked as an apply needs it: usable, offsets 2..5 given.
  // Throws Refused.
  ResultFile usableResult(const std::string& requested, std::string& id) const;
  // Holds the board for session `id` ("is being <held_as>"), shows "<doing> session <id>", and
  // runs `run` on the worker; a worker stopped first ends it with "the daemon stopped before
  // <not_begun>".
  void start(const std::string& id, const std::string& held_as, const std::string& doing,
             const std::string& not_begun, std::function<void()> run);
  void runApply(const std::string& id, const ResultFile& result);
  void runVerify(const std::string& id, const ResultFile& result);
  // The sessions whose folder's apply.jsonl ends inside an online apply, oldest first.
  std::vector<std::string> interruptedApplies() const;
  // Recovers each of `ids` (apply::recoverApply), waiting for a restarting controller first when
  // `wait_for_restart`; what is not recovered blocks the board (unrecovered_).
  void runRecovery(const std::vector<std::string>& ids, bool wait_for_restart);
  void runAcknowledge(const std::vector<std::string>& ids);
  // Closes the unfinished verification sessions of `applied`'s apply, saying `how` it ended.
  void closeVerifications(const std::string& applied, const std::string& how);
  // Why the board is blocked: each unrecovered apply and what to check.
  std::string unrecoveredMessage() const;
  // `wrote`: whether the controller was written; a verification alone that failed leaves the
  // session it verified as it was (done, the failure in the message), never faulted.
  void endApply(const ApplyEvent& event, bool ok, bool wrote = true);

  CellConnection& connection_;
  SessionBoard& board_;
  SessionWorker& worker_;
  SessionStore& store_;
  const CellKnowledge& knowledge_;
  const ManagerSettings& settings_;
  VerificationRun verification_;
  // Worker thread only: the interrupted applies not recovered (id -> why), and what the
  // controller held at the last attempt (empty when it could not be reached).
  std::map<std::string, std::string> unrecovered_;
  std::string last_recovery_seen_;
};

}  // namespace zerocal::service
