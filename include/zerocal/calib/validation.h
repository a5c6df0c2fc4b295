// Hold-out validation: solve on some poses, then ask how well the calibrated model predicts the
// poses it did not see, against the nominal model (zero offsets, nominal laser) on the same
// footing. This is the operator's check that the offsets generalise and are not a fit to noise.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/solver.h"
#include "zerocal/results/holdout_report.h"

namespace zerocal {

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
