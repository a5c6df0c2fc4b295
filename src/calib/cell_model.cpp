#include "zerocal/calib/cell_model.h"

#include <Eigen/Dense>

#include "costs.h"
#include "zerocal/error.h"

namespace zerocal {

Joints CalibrationParameters::offsetsDeg() const {
  Joints out{};
  for (int i = 0; i < kOffsetCount; ++i) out[i + 1] = delta_rad[i] * kRadToDeg;
  return out;
}

std::string unknownName(int i) {
  static const char* names[kUnknownCount] = {
      "delta2_deg",    "delta3_deg",    "delta4_deg",        "delta5_deg",
      "laser_slope_1", "laser_slope_2", "laser_offset_1_mm", "laser_offset_2_mm",
      "target_x_mm",   "target_y_mm",   "target_z_mm"};
  return names[i];
}

Line laserLine(const CellModel& cell, const Joints& q_deg, const CalibrationParameters& params) {
  double q_rad[kJointCount];
  for (int i = 0; i < kJointCount; ++i) q_rad[i] = q_deg[i] * kDegToRad;
  Line line;
  laserLineInBase(cell, q_rad, params.delta_rad.data(), params.laser.data(), &line.point,
                  &line.direction);
  return line;
}

Eigen::Vector3d closestPointToLines(const std::vector<Line>& lines) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const auto& l : lines) {
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - l.direction * l.direction.transpose();
    a += p;
    b += p * l.point;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(a);
  if (!(eig.eigenvalues()[0] > 1e-9 * std::max(1.0, eig.eigenvalues()[2])))
    throw InputError("the laser lines are all parallel: no point is closest to them");
  return a.ldlt().solve(b);
}

Eigen::Vector3d hitPointOffset(const CellModel& cell, const Pose& pose, bool use_readings) {
  if (!use_readings || !pose.spot) return Eigen::Vector3d::Zero();
  return cell.psd_rotation.col(0) * pose.spot->u_mm + cell.psd_rotation.col(1) * pose.spot->v_mm;
}

}  // namespace zerocal
