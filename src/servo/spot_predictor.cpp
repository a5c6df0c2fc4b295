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
  if (!earlier_.empty()) refitChange();
}

void SpotPredictor::expectReadingsOf(const std::vector<Pose>& earlier) {
  earlier_.clear();
  for (const Pose& p : earlier)
    if (p.spot) earlier_.push_back({p.q_deg, Eigen::Vector2d(p.spot->u_mm, p.spot->v_mm)});
  change_.setZero();
  if (!poses_.empty() && !earlier_.empty()) refitChange();
}

const SpotPredictor::Earlier* SpotPredictor::nearestEarlier(const Joints& q) const {
  // A pose aimed at the detector's centre ends this far from its planned joints at most
  // (CalibrationRun's aim); earlier poses lie tens of degrees apart.
  constexpr double kMostAimDeg = 6.0;
  const Earlier* best = nullptr;
  double best_deg = kMostAimDeg;
  for (const Earlier& e : earlier_) {
    double d = 0;
    for (int i = 0; i < kJointCount; ++i) d = std::max(d, std::abs(q[i] - e.q_deg[i]));
    if (d <= best_deg) best_deg = d, best = &e;
  }
  return best;
}

Eigen::Vector2d SpotPredictor::changeAt(const Earlier& e, const Joints& q,
                                        const PredictorState& change) const {
  return spot(change, q) - spot(PredictorState::Zero(), e.q_deg);
}

Eigen::Vector2d SpotPredictor::predicted(const Joints& q) const {
  if (const Earlier* e = nearestEarlier(q)) return e->spot + changeAt(*e, q, change_);
  return spot(x_, q);
}

bool SpotPredictor::predictsFromReading(const Joints& q_deg) const {
  const Earlier* e = nearestEarlier(q_deg);
  return e != nullptr && changeAt(*e, e->q_deg, change_).norm() <= kNearReadingMm;
}

PsdSpot SpotPredictor::predict(const Joints& q_deg) const {
  const Eigen::Vector2d uv = predicted(q_deg);
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
    const Eigen::Vector2d uv = predicted(q);
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

void SpotPredictor::refitChange() {
  // delta1..delta6 since the earlier session, the rest of the state the nominal cell's: the
  // change moves each earlier reading as it moves the nominal spot. Held towards no change with
  // a spread of a degree (a motor or encoder replaced, a lost revolution counter resynchronised
  // by marks), the readings weighed as the arm's scatter in both sessions.
  constexpr double kChangeSpreadRad = 1.0 * kDegToRad;
  constexpr double kReadingMm = 0.05;
  std::vector<std::pair<const Earlier*, std::size_t>> matched;
  for (std::size_t i = 0; i < poses_.size(); ++i)
    if (const Earlier* e = nearestEarlier(poses_[i].first)) matched.emplace_back(e, i);
  PredictorState x = change_;
  const int m = 2 * static_cast<int>(matched.size());
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::MatrixXd j = Eigen::MatrixXd::Zero(m + kJointCount, kJointCount);
    Eigen::VectorXd r(m + kJointCount);
    for (int k = 0; k < static_cast<int>(matched.size()); ++k) {
      const Earlier& e = *matched[static_cast<std::size_t>(k)].first;
      const auto& [q, reading] = poses_[matched[static_cast<std::size_t>(k)].second];
      const Eigen::Vector2d f = e.spot + changeAt(e, q, x);
      r.segment<2>(2 * k) = (f - reading) / kReadingMm;
      for (int c = 0; c < kJointCount; ++c) {
        PredictorState xp = x;
        const double h = 1e-6;
        xp[c] += h;
        j.block<2, 1>(2 * k, c) = (e.spot + changeAt(e, q, xp) - f) / (h * kReadingMm);
      }
    }
    j.bottomRows(kJointCount) =
        Eigen::MatrixXd::Identity(kJointCount, kJointCount) / kChangeSpreadRad;
    r.tail(kJointCount) = x.head<kJointCount>() / kChangeSpreadRad;
    const Eigen::Matrix<double, kJointCount, 1> step =
        -(j.transpose() * j).ldlt().solve(j.transpose() * r);
    x.head<kJointCount>() += step;
    if (step.norm() < 1e-9) break;
  }
  change_ = x;
}

}  // namespace zerocal::servo
