// Hold-out validation: solve on some poses, then ask how well the calibrated model predicts the
// poses it did not see, against the nominal model (zero offsets, nominal laser) on the same
// footing. This is the operator's check that the offsets generalise and are not a fit to noise.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/solver.h"

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

// The aiming error of the line of `params` at joints q against the measured spot
// `target + hit_offset` on the PSD plane through `target` with the cell's PSD orientation.
// A line parallel to the plane gives infinite on-PSD errors.
AimingError aimingError(const CellModel& cell, const Joints& q_deg,
                        const CalibrationParameters& params, const Eigen::Vector3d& target_mm,
                        const Eigen::Vector3d& hit_offset_mm);

// Solves on every pose except `held_out` (1-based, any order, no duplicates) and predicts the
// held-out ones with the identified and with the nominal parameters. Throws InputError when an
// index is out of range or repeated, when no pose is held out, or when fewer than kMinimumPoses
// remain; and whatever solve() throws.
HoldoutReport validateHoldout(const CellModel& cell, const std::vector<Pose>& poses,
                              const std::vector<int>& held_out, const SolveOptions& options = {});

// `count` poses spread evenly over n (1-based): the poses a `--holdout K` holds out, chosen
// deterministically so that a repeat gives the same split. Throws InputError unless
// 1 <= count <= n - kMinimumPoses.
std::vector<int> spreadHoldout(int n, int count);

}  // namespace zerocal
