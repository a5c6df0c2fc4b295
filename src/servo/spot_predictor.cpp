#include "zerocal/servo/spot_predictor.h"

#include <Eigen/Dense>
#include <cmath>

#include "zerocal/model/kinematics.h"
#include "zerocal/servo/servo.h"
#include "zerocal/servo/servo_law.h"

namespace zerocal::servo {
namespace {

// Spread (one sigma) of each unknown before any pose, as the cell is built: offsets uniform in
// +-1 deg on all six joints, laser slopes +-0.02 and point +-5 mm, the centre taught within a few
// mm. All six offsets are unknowns here, unlike in the solver: delta1 and delta6 cannot be told
// apart from the centre and the laser, but they move the spot all the same, and a prior that
// ignores them misplaces the early predictions by centimetres.
PredictorState spread() {
  PredictorState s;
  s << Eigen::Matrix<double, 6, 1>::Constant(0.58 * kDegToRad), 0.012, 0.012, 2.9, 2.9, 5, 5, 5;
  return s;
}

}  // namespace

SpotPredictor::SpotPredictor(const CellModel& cell, const Eigen::Vector3d& taught_centre_mm)
    : cell_(cell), centre_(taught_centre_mm), spread_(spread()) {}

void SpotPredictor::startFrom(const CalibrationParameters& found) {
  prior_.setZero();
  prior_.segment<4>(6) = found.laser;
  prior_.tail<3>() = found.target_mm - centre_;
  // What a calibration leaves unknown: a tenth of a millimetre and 1e-3 of slope cover the
  // line's and centre's few-micrometre sigmas many times over; delta1 and delta6 are absorbed in
  // them. delta2..delta5 keep the build spread (see startFrom's contract).
  spread_.head<6>().setConstant(0.01 * kDegToRad);
  spread_.segment<4>(1) = spread().segment<4>(1);
  spread_.segment<4>(6) << 1e-3, 1e-3, 0.1, 0.1;
  spread_.tail<3>().setConstant(0.1);
  started_from_calibration_ = true;
  x_ = prior_;
  if (!poses_.empty()) refit();
}

Eigen::Vector2d SpotPredictor::spot(const PredictorState& x, const Joints& q) const {
  Joints delta_deg;
  for (int i = 0; i < kJointCount; ++i) delta_deg[i] = x[i] * kRadToDeg;
  const Frame<double> flange = flangePoseDeg(cell_.robot, q, delta_deg);
  Eigen::Vector3d point, direction;
  cell_.laser.line(x.data() + 6, &point, &direction);
  const Eigen::Vector3d p = flange.apply(point), d = flange.R * direction;
  const Eigen::Vector3d c = centre_ + x.tail<3>();
  const Eigen::Vector3d n = cell_.psd_rotation.col(2);
  const double t = n.dot(c - p) / n.dot(d);
  // Relative to the estimated centre, in the PSD frame: the frame the readings are in.
  return (cell_.psd_rotation.transpose() * (p + t * d - c)).head<2>();
}

void SpotPredictor::addPose(const Joints& q_deg, const PsdSpot& spot) {
  poses_.emplace_back(q_deg, Eigen::Vector2d(spot.u_mm, spot.v_mm));
  refit();
}

PsdSpot SpotPredictor::predict(const Joints& q_deg) const {
  const Eigen::Vector2d uv = spot(x_, q_deg);
  return {uv.x(), uv.y()};
}

PsdSpot SpotPredictor::searchCentre(const Joints& q_deg) const {
  return confident() ? predict(q_deg) : PsdSpot{};
}

Joints SpotPredictor::aimedJoints(const Joints& planned, double damping_mm) const {
  if (!confident()) return planned;
  Joints q = planned;
  // Newton steps on the predicted spot: the image Jacobian of the nominal model is within a few
  // percent of the true one, so three steps leave micrometres.
  for (int step = 0; step < 3; ++step) {
    const Eigen::Vector2d uv = spot(x_, q);
    const Eigen::Matrix<double, kJointCount, 2> pinv =
        dampedPseudoInverse(imageJacobian(cell_, centre_ + x_.tail<3>(), q), damping_mm);
    const Eigen::Matrix<double, kJointCount, 1> dq = -pinv * uv;
    for (int i = 0; i < kJointCount; ++i) q[i] += dq[i];
  }
  return q;
}

void SpotPredictor::refit() {
  constexpr int kN = PredictorState::RowsAtCompileTime;
  const PredictorState& s = spread_;
  const int m = 2 * static_cast<int>(poses_.size());
  PredictorState x = x_;
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::MatrixXd j(m + kN, kN);
    Eigen::VectorXd r(m + kN);
    for (int i = 0; i < static_cast<int>(poses_.size()); ++i) {
      const Eigen::Vector2d f = spot(x, poses_[i].first);
      r.segment<2>(2 * i) = f - poses_[i].second;
      for (int k = 0; k < kN; ++k) {
        PredictorState xp = x;
        const double h = 1e-3 * s[k];
        xp[k] += h;
        j.block<2, 1>(2 * i, k) = (spot(xp, poses_[i].first) - f) / h;
      }
    }
    // Maximum a posteriori, the prior in units of each spread and the readings weighted as
    // 0.3 mm: not the robot's repeatability (0.02 mm) but what the arm's link errors, which the
    // model leaves out, make it miss by at every pose (0.1 to 0.3 mm, docs/maths.md section 5).
    // Weighed as repeatability, a few neighbouring poses were fitted to those misses with
    // offsets and a laser far from the truth, and the next pose across the workspace was
    // predicted up to 87 mm off.
    constexpr double kReadingMm = 0.3;
    j.topRows(m) /= kReadingMm;
    r.head(m) /= kReadingMm;
    j.bottomRows(kN) = s.cwiseInverse().asDiagonal();
    r.tail(kN) = (x - prior_).cwiseQuotient(s);
    const PredictorState step = -(j.transpose() * j).ldlt().solve(j.transpose() * r);
    x += step;
    if (step.cwiseQuotient(s).norm() < 1e-6) break;
  }
  x_ = x;
}

}  // namespace zerocal::servo
