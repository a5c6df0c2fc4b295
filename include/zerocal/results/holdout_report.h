// A hold-out validation's result: the "validation" member of result.json and of `solve --json`
// (docs/results.md), and its JSON. zerocal/calib/validation.h computes it.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/results/solve_report.h"

namespace zerocal {

// How far a model's laser line lands from where the spot was measured, for one held-out pose.
// The measured spot is the model's own target point plus the PSD reading (when the poses carry
// readings and the solve used them): h = c + R_psd (u, v, 0). The predicted spot is where the
// model's line at the pose's joints crosses the PSD plane (through c, normal R_psd column 2).
struct AimingError {
  Eigen::Vector2d on_psd_mm = Eigen::Vector2d::Zero();  // predicted - measured, PSD u and v axes
  double on_psd_norm_mm = 0;  // |on_psd_mm|: the spot's distance on the PSD plane
  double miss_mm = 0;         // perpendicular distance of the line from the measured spot
};

struct HeldOutPose {
  int pose = 0;         // 1-based position in the full pose list
  int source_line = 0;  // as in Pose
  AimingError before;   // nominal model, its target fitted to the training poses
  AimingError after;    // identified parameters and target
};

struct HoldoutReport {
  std::vector<int> held_out;  // 1-based, ascending
  int total_poses = 0;
  SolveReport fit;  // the solve on the remaining poses
  // The nominal model's target: the least-squares crossing of the training poses' nominal lines.
  Eigen::Vector3d nominal_target_mm = Eigen::Vector3d::Zero();
  std::vector<HeldOutPose> poses;
  double rms_before_mm = 0, rms_after_mm = 0;  // RMS of on_psd_norm_mm over the held-out poses
};

// The "validation" member of a result; the fit itself is toJson(report.fit).
nlohmann::json toJson(const HoldoutReport& report);
// The inverse of toJson, without the fit (the result around it). Throws InputError.
HoldoutReport holdoutReportFromJson(const nlohmann::json& json, const std::string& where);

}  // namespace zerocal
