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
#include "zerocal/daemon/journal.h"
#include "zerocal/irc5/controller_link.h"
#include "zerocal/servo/psd_reader.h"
#include "zerocal/servo/servo.h"

namespace zerocal {

struct RunSettings {
  servo::ServoOptions servo;
  SolveOptions solve;
};

enum class RunState { kCompleted, kAborted, kFaulted };

// What the run is about to do, for progress display.
enum class RunPhase { kMoving, kServoing, kRecording, kSolving };

struct RunOutcome {
  RunState state = RunState::kFaulted;
  std::string message;                // why it stopped, when not completed
  std::vector<PoseRecord> records;    // every journalled pose, recovered ones included
  int resumed_from = 0;               // poses found in the journal at start
  std::optional<SolveReport> report;  // when completed
};

class CalibrationRun {
 public:
  // `knowledge`: the nominal robot and laser and the PSD's orientation; `taught_centre_mm`: the
  // PSD centre as taught (a few mm off is fine); `plan`: the joint targets. The journal must
  // belong to this plan (its recovered records are taken as its first poses).
  CalibrationRun(CellModel knowledge, Eigen::Vector3d taught_centre_mm, std::vector<Pose> plan,
                 RunSettings settings, Journal& journal);

  // Called after each journalled pose (index, record); for progress display.
  std::function<void(const PoseRecord&)> on_pose;
  // Called before each phase with the 0-based pose index (the pose count for kSolving).
  std::function<void(int pose_index, RunPhase phase)> on_phase;

  // Runs the remaining poses and the solve. `abort` is polled between moves and during the solve
  // (a servo in progress finishes its bounded cycle first). Link and sensor failures end the run
  // as kFaulted with the reason; the journal keeps every pose recorded before.
  RunOutcome run(ControllerLink& robot, servo::PsdReader& psd, servo::CellClock& clock,
                 const std::atomic<bool>& abort);

 private:
  void phase(int pose_index, RunPhase phase) const;

  CellModel knowledge_;
  Eigen::Vector3d taught_centre_;
  std::vector<Pose> plan_;
  RunSettings settings_;
  Journal& journal_;
};

// The recorded poses as the solver takes them (joints with the PSD reading).
std::vector<Pose> posesOf(const std::vector<PoseRecord>& records);

}  // namespace zerocal
