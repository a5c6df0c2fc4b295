#include "zerocal/calib/validation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "zerocal/error.h"

namespace zerocal {

AimingError aimingError(const CellModel& cell, const Joints& q_deg,
                        const CalibrationParameters& params, const Eigen::Vector3d& target_mm,
                        const Eigen::Vector3d& hit_offset_mm) {
  const Line line = laserLine(cell, q_deg, params);
  const Eigen::Vector3d normal = cell.psd_rotation.col(2);
  const Eigen::Vector3d measured = target_mm + hit_offset_mm;
  AimingError e;
  const Eigen::Vector3d to_spot = measured - line.point;
  e.miss_mm = (to_spot - to_spot.dot(line.direction) * line.direction).norm();
  const double along = normal.dot(line.direction);
  if (std::abs(along) < 1e-12) {
    const double inf = std::numeric_limits<double>::infinity();
    e.on_psd_mm = {inf, inf};
    e.on_psd_norm_mm = inf;
    return e;
  }
  // The spot the technician would see: where the beam meets the detector's surface, which for an
  // oblique beam is farther from the measured spot than the line's perpendicular miss.
  const Eigen::Vector3d hit =
      line.point + normal.dot(target_mm - line.point) / along * line.direction;
  const Eigen::Vector3d d = hit - measured;
  e.on_psd_mm = {cell.psd_rotation.col(0).dot(d), cell.psd_rotation.col(1).dot(d)};
  e.on_psd_norm_mm = e.on_psd_mm.norm();
  return e;
}

HoldoutReport validateHoldout(const CellModel& cell, const std::vector<Pose>& poses,
                              const std::vector<int>& held_out, const SolveOptions& options) {
  const int n = static_cast<int>(poses.size());
  if (held_out.empty()) throw InputError("hold-out validation needs at least one held-out pose");
  std::vector<int> sorted = held_out;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    if (sorted[k] < 1 || sorted[k] > n)
      throw InputError("held-out pose " + std::to_string(sorted[k]) + " is not one of the " +
                       std::to_string(n) + " poses (numbered from 1)");
    if (k > 0 && sorted[k] == sorted[k - 1])
      throw InputError("held-out pose " + std::to_string(sorted[k]) + " is given twice");
  }
  const int kept = n - static_cast<int>(sorted.size());
  if (kept < kMinimumPoses)
    throw InputError("holding out " + std::to_string(sorted.size()) + " of " + std::to_string(n) +
                     " poses leaves " + std::to_string(kept) + "; the solve needs at least " +
                     std::to_string(kMinimumPoses));

  std::vector<Pose> training, testing;
  for (int i = 0; i < n; ++i)
    (std::binary_search(sorted.begin(), sorted.end(), i + 1) ? testing : training)
        .push_back(poses[i]);

  HoldoutReport report;
  report.held_out = sorted;
  report.total_poses = n;
  report.fit = solve(cell, training, options);
  const bool readings = report.fit.used_readings;

  // The nominal model gets the same chance as the calibrated one: its own best target from the
  // training poses, so that "before" measures the kinematic error, not an arbitrary target.
  const CalibrationParameters nominal;
  std::vector<Line> lines;
  for (const Pose& pose : training) {
    Line l = laserLine(cell, pose.q_deg, nominal);
    l.point -= hitPointOffset(cell, pose, readings);
    lines.push_back(l);
  }
  report.nominal_target_mm = closestPointToLines(lines);
  CalibrationParameters nominal_with_target = nominal;
  nominal_with_target.target_mm = report.nominal_target_mm;

  double sq_before = 0, sq_after = 0;
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    const Pose& pose = testing[k];
    const Eigen::Vector3d offset = hitPointOffset(cell, pose, readings);
    HeldOutPose h;
    h.pose = sorted[k];
    h.source_line = pose.source_line;
    h.before = aimingError(cell, pose.q_deg, nominal_with_target, report.nominal_target_mm, offset);
    h.after =
        aimingError(cell, pose.q_deg, report.fit.estimate, report.fit.estimate.target_mm, offset);
    sq_before += h.before.on_psd_norm_mm * h.before.on_psd_norm_mm;
    sq_after += h.after.on_psd_norm_mm * h.after.on_psd_norm_mm;
    report.poses.push_back(h);
  }
  report.rms_before_mm = std::sqrt(sq_before / sorted.size());
  report.rms_after_mm = std::sqrt(sq_after / sorted.size());
  return report;
}

std::vector<int> spreadHoldout(int n, int count) {
  if (count < 1 || count > n - kMinimumPoses)
    throw InputError("cannot hold out " + std::to_string(count) + " of " + std::to_string(n) +
                     " poses: between 1 and " + std::to_string(std::max(0, n - kMinimumPoses)) +
                     " can be held out (the solve needs " + std::to_string(kMinimumPoses) + ")");
  std::vector<int> picked;
  // The middle of each of `count` equal slices: spread over the plan, never the same pose twice.
  for (int k = 0; k < count; ++k) picked.push_back(static_cast<int>((k + 0.5) * n / count) + 1);
  return picked;
}

}  // namespace zerocal
