#include "zerocal/calib/cell_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "costs.h"
#include "zerocal/error.h"

namespace zerocal {

Robot withLinkErrors(const Robot& robot,
                     const Eigen::Matrix<double, kLinkParameterCount, 1>& link) {
  Robot out = robot;
  for (int j = 0; j < kJointCount; ++j) {
    out.dh[j].a_mm += link[3 * j];
    out.dh[j].d_mm += link[3 * j + 1];
    out.dh[j].alpha_rad += link[3 * j + 2];
    for (int kind = 0; kind < 3; ++kind) out.identified_link_error[j][kind] += link[3 * j + kind];
  }
  return out;
}

Robot calibratedRobot(const Robot& robot, const CalibrationParameters& params) {
  Robot out = withLinkErrors(robot, params.link);
  for (int k = 0; k < kComplianceCount; ++k)
    out.compliance_deg_per_knm[k] += params.compliance[k] * kRadToDeg;
  return out;
}

double MissNoise::referenceMm() const {
  constexpr double kLeverMm = 1000;
  const double joint_mm = joint_repeatability_deg * kDegToRad * kLeverMm;
  return std::sqrt(joint_mm * joint_mm + psd_mm * psd_mm);
}

Eigen::Matrix2d missCovariance(const CellModel& cell, const Pose& pose,
                               const CalibrationParameters& at, bool use_readings,
                               double noise_mm) {
  if (!cell.noise.perPose()) return noise_mm * noise_mm * Eigen::Matrix2d::Identity();
  DisturbedMiss functor(cell, pose, at, use_readings);
  ceres::AutoDiffCostFunction<DisturbedMiss, 2, kJointCount, 2> cost(&functor,
                                                                     ceres::DO_NOT_TAKE_OWNERSHIP);
  const double zeros[kJointCount] = {};
  const double* blocks[2] = {zeros, zeros};
  Eigen::Matrix<double, 2, kJointCount, Eigen::RowMajor> jq;
  Eigen::Matrix<double, 2, 2, Eigen::RowMajor> juv;
  double* jacobians[2] = {jq.data(), juv.data()};
  double miss[2];
  cost.Evaluate(blocks, miss, jacobians);
  const double sq = cell.noise.joint_repeatability_deg * kDegToRad;
  return sq * sq * jq * jq.transpose() +
         cell.noise.psd_mm * cell.noise.psd_mm * juv * juv.transpose();
}

CellModel atDetector(CellModel cell) {
  cell.noise = {};
  return cell;
}

Eigen::Matrix2d missWeight(const CellModel& cell, const Pose& pose, const CalibrationParameters& at,
                           bool use_readings) {
  if (!cell.noise.perPose()) return Eigen::Matrix2d::Identity();
  // W = s_ref Sigma^-1/2 (symmetric), so that W Sigma W^T = s_ref^2 I.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(
      missCovariance(cell, pose, at, use_readings, 0));
  const Eigen::Vector2d inv_sqrt = eig.eigenvalues().cwiseMax(1e-30).cwiseSqrt().cwiseInverse();
  return cell.noise.referenceMm() * eig.eigenvectors() * inv_sqrt.asDiagonal() *
         eig.eigenvectors().transpose();
}

const Eigen::Matrix3d& CellModel::psdRotation(int placement) const {
  const std::size_t k = static_cast<std::size_t>(placement - 2);
  return placement >= 2 && k < placement_rotations.size() ? placement_rotations[k] : psd_rotation;
}

Line laserLine(const CellModel& cell, const Joints& q_deg, const CalibrationParameters& params) {
  double q_rad[kJointCount];
  jointsRad(cell.robot, q_deg, q_rad);
  Line line;
  if (params.link.isZero(0) && params.compliance.isZero(0)) {
    laserLineInBase(cell, q_rad, params.delta_rad.data(), params.laser.data(), &line.point,
                    &line.direction);
  } else {
    const auto torque = gravityTorqueKnm(cell.robot, cell.robot.masses, q_deg);
    const Frame<double> flange =
        flangeWithLinkErrors(cell.robot, q_rad, params.delta_rad.data(), params.link.data(),
                             params.compliance.data(), torque.data());
    Eigen::Vector3d p, d;
    cell.laser.line(params.laser.data(), &p, &d);
    line.point = flange.apply(p);
    line.direction = flange.R * d;
  }
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
  const Eigen::Matrix3d& r = cell.psdRotation(pose.placement);
  return r.col(0) * pose.spot->u_mm + r.col(1) * pose.spot->v_mm;
}

}  // namespace zerocal
