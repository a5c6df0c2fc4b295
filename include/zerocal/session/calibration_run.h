// One calibration run: move to each planned pose, servo the spot onto the PSD, journal the pose
// (on disk before the next move), then solve. A run resumes from its journal: poses already
// recorded are neither repeated nor lost. The daemon drives this; the seams (ControllerLink,
// PsdReader, CellClock) are passed in, so the same code runs on the simulated cell and a real one.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/solver.h"
#include "zerocal/cell/controller_link.h"
#include "zerocal/cell/psd_reader.h"
#include "zerocal/servo/servo.h"
#include "zerocal/store/journal.h"

namespace zerocal {

struct RunSettings {
  // settle_s is applied through the clock given to run(); `abort` is set by run() to its flag.
  servo::ServoOptions servo;
  SolveOptions solve;

  // Recovery from a lost link or board. When the controller link fails with a transient
  // LinkError (a move throws one, or the servo latches kLinkError of that kind) and
  // `reconnect_link` is set, it is called (the daemon wires ControllerConnection::reconnect,
  // which retries with back-off of its own) and the current pose, not yet journalled, is done
  // again from its planned move. Likewise `reopen_sensor` (PsdReadout::reopen) when the PSD
  // reader fails with a transient error. A refused or fatal error is never recovered. A hook
  // that throws is called again after recovery_backoff_s of cell time, up to recovery_attempts
  // calls per failure; at most recoveries_per_pose failures are recovered per pose. Unset hooks:
  // the failure faults the run.
  std::function<void()> reconnect_link;
  std::function<void()> reopen_sensor;
  int recovery_attempts = 3;
  double recovery_backoff_s = 2.0;
  int recoveries_per_pose = 2;
  // The most poses measured again when the solve names them (0: none): a session of poses with
  // no gross error measures none again.
  int remeasure_most = 3;
  // What solves the measured poses: the absolute solve (zerocal/calib/solver.h) when unset. A
  // session measured against a reference sets its own (the change since it); plan_indices[k] is
  // poses[k]'s 0-based plan pose.
  std::function<SolveReport(const std::vector<Pose>& poses, const std::vector<int>& plan_indices,
                            const SolveOptions& options)>
      solver;
};

// kAwaitingPlacement: every pose of the PSD's placement is recorded and the next plan pose is at
// the next placement; the run stopped before moving there, for the technician to move the PSD.
enum class RunState { kCompleted, kAborted, kFaulted, kAwaitingPlacement };

// Called before each phase; pose_index is 0-based (the plan's size for kSolving).
enum class RunPhase { kMoving, kServoing, kRecording, kSolving };

struct RunOutcome {
  RunState state = RunState::kFaulted;
  std::string message;                // why it stopped, when not completed
  std::vector<PoseRecord> records;    // every journalled pose, recovered ones included
  int resumed_from = 0;               // poses found in the journal at start
  std::optional<SolveReport> report;  // when completed
  int reconnects = 0;                 // link failures recovered
  int reopens = 0;                    // board failures recovered
  int stopped_at = -1;                // 0-based pose at which a faulted run stopped
  std::vector<int> remeasured;        // 0-based plan poses measured again after the first solve
  // The fault is the pose's own: its spot was never found or lost, the servo did not converge,
  // or the target was refused. Measuring it again would fail again; skipping it may not.
  bool pose_at_fault = false;
  int next_placement = 0;  // kAwaitingPlacement: the placement the PSD is to be moved to
};

class CalibrationRun {
 public:
  // `knowledge`: the nominal robot and laser and the PSD's orientation (at each placement);
  // `taught_centre_mm`: the PSD centre as taught (a few mm off is fine), placement 1's; `plan`:
  // the joint targets, each with its placement (1, then 2, ... in turn). The journal must belong
  // to this plan (its recovered records are taken as its first poses); its placement lines give
  // the later placements' taught centres. Throws InputError when the plan's placements are not
  // 1, 2, ... in turn or the journal's PSD placement is ahead of its next pose.
  CalibrationRun(CellModel knowledge, Eigen::Vector3d taught_centre_mm, std::vector<Pose> plan,
                 RunSettings settings, Journal& journal);

  // The cell as the calibration being verified found it, its offsets since written to the
  // controller: where the spot lands is then predicted from the first pose
  // (servo::SpotPredictor::startFrom). Unset for a calibration.
  std::optional<CalibrationParameters> found_before;
  // The poses of the session this one re-measures (a check's, restore's or verification's
  // reference; joints and readings): the plan's poses are their joints, and the spot is expected
  // where that session read it (servo::SpotPredictor::expectReadingsOf). Empty for a calibration.
  std::vector<Pose> earlier;

  // Called after each journalled pose (index, record); for progress display.
  std::function<void(const PoseRecord&)> on_pose;
  // Called before each phase of each pose, and before the solve.
  std::function<void(int pose_index, RunPhase phase)> on_phase;
  // Called when the solve named poses that are now measured again (0-based plan poses).
  std::function<void(const std::vector<int>& plan_indices)> on_remeasure;

  // Runs the remaining poses of the PSD's placement; when the next plan pose is at the next
  // placement, stops there (kAwaitingPlacement, the robot at rest after its last pose) until
  // placeNext() has journalled the move; after the last pose, the solve (the several-placement
  // solve when the poses are at two or more placements). `abort` is polled before every move (the
  // servo polls it each cycle: an abort during a long search stops within one servo move) and
  // during the solve; on abort the robot is left at rest where its last move ended. Link and sensor
  // failures are recovered through the settings' hooks when set, else (or when recovery fails) end
  // the run as kFaulted with the pose and the reason; the journal keeps every pose recorded before,
  // and the robot is at rest (every move is a blocking fine-point move, so none is under way). When
  // the spot is not found the robot is back at the planned pose, a pose checked against the
  // limits before the run started (the "safe pose"). Every fault the servo latches (an abort
  // excepted) is appended with its recent samples to faults.jsonl beside the journal
  // (appendFault) before the run recovers or stops; throws JournalError when that or a journal
  // line cannot be written.
  RunOutcome run(ControllerLink& robot, PsdReader& psd, CellClock& clock,
                 const std::atomic<bool>& abort);

  // Journals the next plan pose as skipped, for `reason`, before run(): no solve uses it and no
  // later run measures it (on_pose is called with its record). Throws InputError when every plan
  // pose is recorded already, JournalError when the line cannot be written.
  void skipNextPose(const std::string& reason);

  // The placement the next plan pose is at when the run waits for the PSD to be moved (run()
  // returned kAwaitingPlacement, or would at once); 0 when it does not wait.
  int awaitedPlacement() const;
  // Journals that the PSD now stands at the awaited placement, with its centre as taught (base
  // frame, mm), before run() goes on there. Throws InputError when no placement is awaited,
  // JournalError when the line cannot be written.
  void placeNext(const Eigen::Vector3d& centre_mm);

 private:
  // Appends the servo's latched fault at plan pose `plan_index` to faults.jsonl.
  void journalFault(const servo::ServoFault& fault, int plan_index, bool again) const;
  // The PSD as the session knows it at a placement: the model with that placement's orientation,
  // and its taught centre (the journal's placement line; taught_centre_ for the first).
  CellModel placementModel(int placement) const;
  Eigen::Vector3d placementCentre(int placement) const;

  CellModel knowledge_;
  Eigen::Vector3d taught_centre_;
  std::vector<Pose> plan_;
  RunSettings settings_;
  Journal& journal_;
};

// The measured poses as the solver takes them (joints with the PSD reading and the placement):
// each plan pose's latest measurement (latestRecords), in plan order; skipped ones left out. Each
// keeps its record's journal line as its source_line, so the solve's residuals and messages name
// the line.
std::vector<Pose> posesOf(const std::vector<PoseRecord>& records);
// The 0-based plan pose of each of posesOf's poses.
std::vector<int> planIndicesOf(const std::vector<PoseRecord>& records);

}  // namespace zerocal
