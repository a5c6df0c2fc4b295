// result.json (docs/results.md): a solve and what the daemon knew of the run and the cell, and
// its JSON. The daemon writes it, the report, the lab's commands and the technician's client read
// it (the control port's `result` sends it as it is).
// Reading is strict about what a reader needs and tolerant of members it does not know, so that a
// newer file still reads; fromJson(toJson(x)) gives x back, and toJson(fromJson(j)) gives j for
// every file zerocal writes.
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/cell/robot_info.h"
#include "zerocal/results/check_judgement.h"
#include "zerocal/results/holdout_report.h"
#include "zerocal/results/servo_stats.h"
#include "zerocal/results/session_file.h"
#include "zerocal/results/solve_report.h"

namespace zerocal {

// One pose of result.json's "pose_breakdown": where its cell time went.
struct PoseTimes {
  int pose = 0;         // 1-based plan pose
  std::string skipped;  // why, when the pose was skipped (nothing else is then known)
  bool again = false;   // its second measurement
  ServoStats servo;
  // What every move costs the controller beyond its motion, when the cell knows it (the
  // simulated controller), for all moves of the pose; included in the times of `servo`.
  std::optional<double> move_overhead_s, fine_point_settle_s;
};

// result.json: the solve (the top-level members) and the daemon's members around it. Members
// written by some writers only are optional: a result of `zerocal solve` has no cell time.
struct ResultFile {
  SolveReport report;
  // False for a result written before verdicts were recorded: its "verdict" is absent, and a
  // reader judges by convergence and identifiability alone.
  bool verdict_recorded = true;
  std::optional<HoldoutReport> validation;  // when poses were held out of the solve
  std::string session;                      // the session's id; empty when not a session's
  // What the session was for. A check's, a restore's and a restore's verification's report is
  // the change since `reference` (the reference session's id): its offsets are the change of
  // each zero, written as "change" too; a check adds its judgement.
  SessionKind kind = SessionKind::kCalibration;
  std::string reference;
  std::optional<CheckJudgement> check;
  // The robot model: the calibration whose calibrated model (its model_file) the solve used in
  // place of the daemon's robot file, empty when it used the robot file; and the calibrated
  // model this session wrote beside its result (a usable calibration at several placements:
  // its identified link errors with their covariance, for later sessions), empty when none.
  std::string model_from;
  std::string model_file;
  // Against a reference: the zeros that moved since the robot's last comparison with it.
  std::vector<Drift> drift;
  std::optional<double> cell_time_s;
  std::optional<int> resumed_from;
  std::optional<std::vector<int>> remeasured;  // 1-based plan poses measured again
  struct Cell {
    RobotInfo controller;  // as the controller named the robot
    std::string psd_map;   // the map's file and fingerprint
  };
  std::optional<Cell> cell;
  // The controller's motor calibration (MOC cal_offset of joints 1..6, rad in [0, 2 pi)) while
  // the session measured: the values its offsets are relative to. An online apply refuses when
  // the controller holds others. Absent when the link offers no calibration (or an older file).
  std::optional<std::array<double, 6>> cal_offset_rad;
  std::string zerocal_version;  // empty: not recorded
  std::optional<std::int64_t> finished_unix_s;
  struct Recoveries {
    int reconnects = 0, reopens = 0;
  };
  std::optional<Recoveries> recoveries;
  // A simulated session's true offsets (deg, delta2..delta5) and the file of its whole world.
  struct Truth {
    std::array<double, 4> offsets_deg{};
    std::string world_file;  // empty: not written
    // The seed the session's noise was drawn from (WorldNoise::seed); nullopt: not recorded.
    std::optional<std::uint64_t> noise_seed;
  };
  std::optional<Truth> truth;
  std::optional<std::vector<PoseTimes>> pose_breakdown;
};

nlohmann::json toJson(const ResultFile& result);
// Throws InputError naming "result.json" and the member.
ResultFile resultFileFromJson(const nlohmann::json& json);

}  // namespace zerocal
