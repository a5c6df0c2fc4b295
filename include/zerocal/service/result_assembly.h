// A finished session's result.json from what its run produced: a pure function of the run's
// outcome and what the session learned of the cell, so that it is tested without a thread or a
// cell (tests/service/result_assembly_test.cpp).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/cell/controller_link.h"
#include "zerocal/session/calibration_run.h"
#include "zerocal/store/session_files.h"

namespace zerocal::service {

// What a session learned of the cell around its poses.
struct RunFacts {
  SessionKind kind = SessionKind::kCalibration;
  std::string reference;                // the reference session measured against, if any
  std::optional<CheckJudgement> check;  // a check's judgement
  std::string model_from;               // ResultFile::model_from
  std::string model_file;               // ResultFile::model_file
  std::vector<Drift> drift;             // zeros moved since the last comparison
  ResultFile::Cell cell;                // the controller as it named the robot, the PSD map
  // The controller's motor calibration while the session measured (rad); absent when its link
  // offers none or it did not answer.
  std::optional<std::array<double, 6>> cal_offset_rad;
  double cell_time_s = 0;  // the run's cell time, from the first connect to the solve
  // A simulated cell's true offsets (deg, delta2..delta5) and the file its world is written to
  // beside the result (empty: none written).
  std::optional<std::array<double, 4>> truth_deg;
  std::string truth_world_file;
  std::optional<std::uint64_t> truth_noise_seed;
  std::int64_t finished_unix_s = 0;
  // What every move costs the controller beyond its motion, when known: each measured pose's
  // breakdown then shows it, as moves x cost.
  std::optional<MoveOverhead> move_overhead;
};

// The result of a completed run (outcome.report set) of session `session_id`: the solve, the
// run's counts (resumed, measured again, recoveries), the facts, and each journalled pose's
// times in the pose breakdown.
ResultFile assembleResult(const std::string& session_id, const RunOutcome& outcome,
                          const RunFacts& facts);

// Each offset's achieved standard deviation (deg, delta2..delta5); NaN where not identified.
std::vector<double> achievedSigma(const SolveReport& report);

}  // namespace zerocal::service
