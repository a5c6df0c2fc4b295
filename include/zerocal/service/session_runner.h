// A session's run on the worker thread, by its kind (SessionFile::kind): a calibration and a
// verification measure the plan's poses and solve (CalibrationRun), then write the result. A new
// kind is a function of its own beside them, chosen in run().
//
// What every kind shares: connecting and identifying the cell (CellConnection), the board's
// phases and events, ending the run (finish).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>

#include "zerocal/service/cell_connection.h"
#include "zerocal/service/live_reading.h"
#include "zerocal/service/manager_settings.h"
#include "zerocal/service/request_planner.h"
#include "zerocal/service/result_assembly.h"
#include "zerocal/service/session_board.h"
#include "zerocal/service/session_worker.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

// A session to run (or go on with) now.
struct RunRequest {
  std::string id;
  SessionKind kind = SessionKind::kCalibration;
  RunPlan plan;
  // The 0-based plan pose to journal as skipped before running (-1: none), and why.
  int skip_index = -1;
  std::string skip_reason;
  // A verification's: the calibration it verifies (CalibrationRun::found_before).
  std::optional<CalibrationParameters> found_before;
  // A continue: first journals that the PSD stands at the placement the session waits for,
  // taught at this centre.
  std::optional<Eigen::Vector3d> place_next;
};

class SessionRunner {
 public:
  // Every part outlives the runner.
  SessionRunner(CellConnection& connection, SessionBoard& board, SessionWorker& worker,
                SessionStore& store, const RequestPlanner& planner, const CellKnowledge& knowledge,
                LiveReadingSlot& live, const ManagerSettings& settings);

  // Runs the session by its kind, on the worker thread, and ends it on the board (done,
  // aborted, faulted) or leaves it waiting for a PSD placement. Never throws.
  void run(const RunRequest& request);
  // Ends the run (the robot stopped unless done) and logs why.
  void finish(SessionState state, const std::string& message);

 private:
  // A calibration or a verification: the plan's poses measured, solved, the result written.
  void runMeasurement(const RunRequest& request);
  // The completed run's result.json, reports and events.
  void complete(const std::string& id, const RunOutcome& outcome, RunFacts facts);
  void setPhase(SessionState state, int pose);

  CellConnection& connection_;
  SessionBoard& board_;
  SessionWorker& worker_;
  SessionStore& store_;
  const RequestPlanner& planner_;
  const CellKnowledge& knowledge_;
  LiveReadingSlot& live_;
  const ManagerSettings& settings_;
};

}  // namespace zerocal::service
