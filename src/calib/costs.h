// Cost functors of the identification. Each is templated for Ceres' automatic differentiation
// and checked with ceres::GradientChecker in tests/calib/costs_test.cpp.
#pragma once

#include <ceres/ceres.h>

#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {

// Controller joints (deg) as the radians the kinematics turns, with the deflection of the robot
// file's identified compliance (a calibrated model) added: constant per pose.
inline void jointsRad(const Robot& robot, const Joints& q_deg, double* q_rad) {
  const Joints sag = complianceDeflectionDeg(robot, q_deg);
  for (int i = 0; i < kJointCount; ++i) q_rad[i] = (q_deg[i] + sag[i]) * kDegToRad;
}

// Flange pose for controller joints q (radians) with the offsets delta2..delta5 added.
template <typename T>
Frame<T> flangeWithOffsets(const Robot& robot, const double* q_rad, const T* delta) {
  const T joints[kJointCount] = {T(q_rad[0]),
                                 T(q_rad[1]) + delta[0],
                                 T(q_rad[2]) + delta[1],
                                 T(q_rad[3]) + delta[2],
                                 T(q_rad[4]) + delta[3],
                                 T(q_rad[5])};
  return flangePose(robot, joints);
}

// One DH link with its errors: Rz(theta) Tz(d + dd) Tx(a + da) Rx(alpha + dalpha), error =
// (da, dd, dalpha) in mm, mm, rad; theta in radians, the row's theta offset added.
template <typename T>
Frame<T> dhLinkWithErrors(const DhRow& row, const T& joint_rad, const T* error) {
  using std::cos;
  using std::sin;
  const T theta = joint_rad + T(row.theta_offset_rad);
  const T alpha = T(row.alpha_rad) + error[2];
  const T ct = cos(theta), st = sin(theta), ca = cos(alpha), sa = sin(alpha);
  const T a = T(row.a_mm) + error[0];
  Frame<T> f;
  f.R << ct, -st * ca, st * sa,  //
      st, ct * ca, -ct * sa,     //
      T(0), sa, ca;
  f.p << a * ct, a * st, T(row.d_mm) + error[1];
  return f;
}

// Flange pose with the offsets delta2..delta5, the link errors (kLinkParameterCount, in
// linkParamName order) and the compliance of joints 2 and 3 (rad per kN m, times the pose's
// gravity torque in kN m) added.
template <typename T>
Frame<T> flangeWithLinkErrors(const Robot& robot, const double* q_rad, const T* delta,
                              const T* link, const T* compliance, const double* torque_knm) {
  const T joints[kJointCount] = {T(q_rad[0]),
                                 T(q_rad[1]) + delta[0] + compliance[0] * torque_knm[0],
                                 T(q_rad[2]) + delta[1] + compliance[1] * torque_knm[1],
                                 T(q_rad[3]) + delta[2],
                                 T(q_rad[4]) + delta[3],
                                 T(q_rad[5])};
  Frame<T> f = dhLinkWithErrors(robot.dh[0], joints[0], link);
  for (int i = 1; i < kJointCount; ++i)
    f = f * dhLinkWithErrors(robot.dh[i], joints[i], link + 3 * i);
  return f;
}

// Laser line of one pose in the base frame, differentiable in the offsets and laser parameters.
template <typename T>
void laserLineInBase(const CellModel& cell, const double* q_rad, const T* delta, const T* kappa,
                     Vec3<T>* point, Vec3<T>* direction) {
  const Frame<T> flange = flangeWithOffsets(cell.robot, q_rad, delta);
  Vec3<T> p, d;
  cell.laser.line(kappa, &p, &d);
  *point = flange.apply(p);
  *direction = flange.R * d;
}

// The miss of the laser line (flange pose `flange`, laser parameters kappa) from the hit point
// target + offset, along b1, b2, divided by sigma: the residual of the point-to-line costs below.
template <typename T>
void pointToLineMiss(const CellModel& cell, const Frame<T>& flange, const T* kappa, const T* target,
                     const Eigen::Vector3d& offset, const Eigen::Matrix2d& weight, T* residual) {
  Vec3<T> p, d;
  cell.laser.line(kappa, &p, &d);
  const Vec3<T> hit(target[0] + offset[0], target[1] + offset[1], target[2] + offset[2]);
  const Vec3<T> w = flange.R.transpose() * (hit - flange.p) - p;
  const Vec3<T> e1 = cell.laser.e1().cast<T>();
  Vec3<T> b1 = e1 - e1.dot(d) * d;
  b1 /= b1.norm();
  const Vec3<T> b2 = d.cross(b1);
  const T m1 = b1.dot(w), m2 = b2.dot(w);
  residual[0] = weight(0, 0) * m1 + weight(0, 1) * m2;
  residual[1] = weight(1, 0) * m1 + weight(1, 1) * m2;
}

// The miss of pose's line from its hit point (as pointToLineMiss, unweighed) when the arm stands
// at the pose's joints turned by dq (rad, the six joints) and the reading is off by duv (mm, the
// detector's u and v): what the arm's repeatability and the detector's noise do to the miss, for
// MissNoise's covariance. The offsets, laser and target are those of the parameters held.
class DisturbedMiss {
 public:
  DisturbedMiss(const CellModel& cell, const Pose& pose, const CalibrationParameters& at,
                bool readings)
      : cell_(cell),
        at_(at),
        offset_(hitPointOffset(cell, pose, readings)),
        psd_(cell.psdRotation(pose.placement)) {
    jointsRad(cell.robot, pose.q_deg, q_rad_);
  }

  template <typename T>
  bool operator()(const T* dq, const T* duv, T* residual) const {
    T joints[kJointCount];
    for (int j = 0; j < kJointCount; ++j)
      joints[j] =
          T(q_rad_[j]) + dq[j] + (j >= 1 && j <= kOffsetCount ? T(at_.delta_rad[j - 1]) : T(0));
    const Frame<T> flange = flangePose(cell_.robot, joints);
    T kappa[kLaserParamCount], target[kTargetCount];
    for (int k = 0; k < kLaserParamCount; ++k) kappa[k] = T(at_.laser[k]);
    for (int k = 0; k < kTargetCount; ++k)
      target[k] = T(at_.target_mm[k]) + T(psd_(k, 0)) * duv[0] + T(psd_(k, 1)) * duv[1];
    pointToLineMiss(cell_, flange, kappa, target, offset_, Eigen::Matrix2d::Identity(), residual);
    return true;
  }

 private:
  const CellModel& cell_;
  CalibrationParameters at_;
  double q_rad_[kJointCount];
  Eigen::Vector3d offset_;
  Eigen::Matrix3d psd_;
};

// Maximum likelihood, target explicit (point-to-line).
//
//   h_i = c + o_i                     o_i = R_psd (u_i, v_i, 0), or 0 without a reading
//   w   = R_6(q_i, delta)^T (h_i - t_6(q_i, delta)) - p_E(kappa)    (in the flange frame)
//   r_i = [ b1 . w ; b2 . w ] / sigma
//
// where b1, b2 span the plane normal to the laser direction d_E(kappa) (b1 = e1 made orthogonal
// to d_E, b2 = d_E x b1, smooth near the nominal). r_i is the miss distance of the line from
// the hit point, in units of the measurement sigma: 2 residuals per pose.
class PointToLineCost {
 public:
  // `weight`: the pose's missWeight (the identity for one noise for every pose).
  PointToLineCost(const CellModel& cell, const Joints& q_deg, const Eigen::Vector3d& hit_offset,
                  double sigma_mm, const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity())
      : cell_(cell), offset_(hit_offset), weight_(weight / sigma_mm) {
    jointsRad(cell.robot, q_deg, q_rad_);
  }

  template <typename T>
  bool operator()(const T* delta, const T* kappa, const T* target, T* residual) const {
    const Frame<T> flange = flangeWithOffsets(cell_.robot, q_rad_, delta);
    pointToLineMiss(cell_, flange, kappa, target, offset_, weight_, residual);
    return true;
  }

  static ceres::CostFunction* create(const CellModel& cell, const Joints& q_deg,
                                     const Eigen::Vector3d& hit_offset, double sigma_mm,
                                     const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity()) {
    return new ceres::AutoDiffCostFunction<PointToLineCost, 2, kOffsetCount, kLaserParamCount,
                                           kTargetCount>(
        new PointToLineCost(cell, q_deg, hit_offset, sigma_mm, weight));
  }

 private:
  const CellModel& cell_;
  double q_rad_[kJointCount];
  Eigen::Vector3d offset_;
  Eigen::Matrix2d weight_;
};

// Point-to-line with the link errors and the compliance of joints 2 and 3 as unknowns too
// (several PSD placements, each with its own target c_p): the same residual as PointToLineCost,
//
//   theta_j = q_j + delta_j + c_j tau_j(q)         j = 2, 3 (the other joints: q_j + delta_j)
//   w   = R_6(theta, lambda)^T (c_p + o_i - t_6(theta, lambda)) - p_E(kappa)
//   r_i = [ b1 . w ; b2 . w ] / sigma
//
// with lambda the 18 link errors (da, dd, dalpha of each joint) in the DH rows, c_j the
// compliance (rad per kN m) and tau_j(q) the gravity torque of the robot file's masses at the
// commanded joints (kN m; zero without a gravity model): a joint yields in proportion to the
// torque it carries. The torque is computed once per pose on the nominal arm; the link errors
// and offsets change it by far less than the compliance can resolve.
class LinkPointToLineCost {
 public:
  LinkPointToLineCost(const CellModel& cell, const Joints& q_deg, const Eigen::Vector3d& hit_offset,
                      double sigma_mm, const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity())
      : cell_(cell), offset_(hit_offset), weight_(weight / sigma_mm) {
    jointsRad(cell.robot, q_deg, q_rad_);
    const auto torque = gravityTorqueKnm(cell.robot, cell.robot.masses, q_deg);
    for (int k = 0; k < kComplianceCount; ++k) torque_knm_[k] = torque[k];
  }

  template <typename T>
  bool operator()(const T* delta, const T* kappa, const T* link, const T* compliance,
                  const T* target, T* residual) const {
    const Frame<T> flange =
        flangeWithLinkErrors(cell_.robot, q_rad_, delta, link, compliance, torque_knm_);
    pointToLineMiss(cell_, flange, kappa, target, offset_, weight_, residual);
    return true;
  }

  static ceres::CostFunction* create(const CellModel& cell, const Joints& q_deg,
                                     const Eigen::Vector3d& hit_offset, double sigma_mm,
                                     const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity()) {
    return new ceres::AutoDiffCostFunction<LinkPointToLineCost, 2, kOffsetCount, kLaserParamCount,
                                           kLinkParameterCount, kComplianceCount, kTargetCount>(
        new LinkPointToLineCost(cell, q_deg, hit_offset, sigma_mm, weight));
  }

 private:
  const CellModel& cell_;
  double q_rad_[kJointCount];
  double torque_knm_[kComplianceCount];
  Eigen::Vector3d offset_;
  Eigen::Matrix2d weight_;
};

// The paper's cost (eq. 6), kept for comparison. For every pair (i < j) of laser lines the
// midpoint of their common perpendicular
//
//   s = (b e - d) / (1 - b^2),  t = (e - b d) / (1 - b^2),
//   b = d_i.d_j,  d = d_i.(p_i - p_j),  e = d_j.(p_i - p_j)
//   P_k = ((p_i + s d_i) + (p_j + t d_j)) / 2
//
// and the residuals P_k - mean_k(P_k), 3 per pair, scaled by 1/sigma. No target unknown.
// Near-parallel pairs make 1 - b^2 small and dominate: the reason this is not the default.
class PairwiseCost {
 public:
  PairwiseCost(const CellModel& cell, const std::vector<Pose>& poses, double sigma_mm)
      : cell_(cell), inv_sigma_(1.0 / sigma_mm) {
    for (const auto& pose : poses) {
      std::array<double, kJointCount> q;
      jointsRad(cell.robot, pose.q_deg, q.data());
      q_rad_.push_back(q);
    }
  }

  int residualCount() const {
    const int n = static_cast<int>(q_rad_.size());
    return 3 * n * (n - 1) / 2;
  }

  template <typename T>
  bool operator()(T const* const* params, T* residual) const {
    const int n = static_cast<int>(q_rad_.size());
    std::vector<Vec3<T>> p(n), d(n);
    for (int i = 0; i < n; ++i)
      laserLineInBase(cell_, q_rad_[i].data(), params[0], params[1], &p[i], &d[i]);
    midpointResiduals(p, d, inv_sigma_, residual);
    return true;
  }

  // The residuals for given base-frame lines (unit directions); also used to propagate the
  // measurement noise through this estimator.
  template <typename T>
  static void midpointResiduals(const std::vector<Vec3<T>>& p, const std::vector<Vec3<T>>& d,
                                double inv_sigma, T* residual) {
    const int n = static_cast<int>(p.size());
    Vec3<T> mean = Vec3<T>::Zero();
    int k = 0;
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j, ++k) {
        const Vec3<T> w0 = p[i] - p[j];
        const T b = d[i].dot(d[j]), dd = d[i].dot(w0), e = d[j].dot(w0);
        const T denom = T(1) - b * b;
        const T s = (b * e - dd) / denom, t = (e - b * dd) / denom;
        const Vec3<T> mid = T(0.5) * (p[i] + s * d[i] + p[j] + t * d[j]);
        for (int c = 0; c < 3; ++c) residual[3 * k + c] = mid[c];
        mean += mid;
      }
    mean /= T(k);
    for (int m = 0; m < k; ++m)
      for (int c = 0; c < 3; ++c) residual[3 * m + c] = (residual[3 * m + c] - mean[c]) * inv_sigma;
  }

  static ceres::CostFunction* create(const CellModel& cell, const std::vector<Pose>& poses,
                                     double sigma_mm) {
    auto* functor = new PairwiseCost(cell, poses, sigma_mm);
    auto* cost = new ceres::DynamicAutoDiffCostFunction<PairwiseCost, kIdentifiedCount>(functor);
    cost->AddParameterBlock(kOffsetCount);
    cost->AddParameterBlock(kLaserParamCount);
    cost->SetNumResiduals(functor->residualCount());
    return cost;
  }

 private:
  const CellModel& cell_;
  std::vector<std::array<double, kJointCount>> q_rad_;
  double inv_sigma_;
};

}  // namespace zerocal
