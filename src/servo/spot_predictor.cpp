#include "zerocal/servo/spot_predictor.h"

#include <Eigen/Dense>
#include <cmath>

#include "zerocal/model/kinematics.h"

namespace zerocal::servo {
namespace {

using Vector11 = Eigen::Matrix<double, 11, 1>;

// Expected spread of each unknown before any pose: offsets up to 1 deg; laser slopes ~0.02 plus
// what delta6 (not identifiable, absorbed here) adds; laser point within ~5 mm; the centre as
// taught within a few mm plus what delta1 (absorbed into it) moves it, ~16 mm at the PSD's reach.
// The damping is measured in these units.
Vector11 spread() {
  Vector11 s;
  s << Eigen::Vector4d::Constant(1.0 * kDegToRad), 0.04, 0.04, 5, 5, 20, 20, 20;
  return s;
}

}  // namespace

SpotPredictor::SpotPredictor(const CellModel& cell, const Eigen::Vector3d& taught_centre_mm)
    : cell_(cell), centre_(taught_centre_mm) {}

Eigen::Vector2d SpotPredictor::spot(const Vector11& x, const Joints& q) const {
  CalibrationParameters p;
  p.delta_rad = x.head<4>();
  p.laser = x.segment<4>(4);
  const Eigen::Vector3d c = centre_ + x.tail<3>();
  const Line line = laserLine(cell_, q, p);
  const Eigen::Vector3d n = cell_.psd_rotation.col(2);
  const double t = n.dot(c - line.point) / n.dot(line.direction);
  // Relative to the taught centre, in the PSD frame: the frame the readings are in once the
  // centre offset is part of the unknowns.
  return (cell_.psd_rotation.transpose() * (line.point + t * line.direction - c)).head<2>();
}

void SpotPredictor::addPose(const Joints& q_deg, const Eigen::Vector2d& uv_mm) {
  poses_.emplace_back(q_deg, uv_mm);
  refit();
}

Eigen::Vector2d SpotPredictor::predict(const Joints& q_deg) const { return spot(x_, q_deg); }

Eigen::Vector2d SpotPredictor::searchCentre(const Joints& q_deg) const {
  return poseCount() >= kConfidentPoses ? predict(q_deg) : Eigen::Vector2d::Zero();
}

void SpotPredictor::refit() {
  const Vector11 s = spread();
  const int m = 2 * static_cast<int>(poses_.size());
  Vector11 x = x_;
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::MatrixXd j(m + 11, 11);
    Eigen::VectorXd r(m + 11);
    for (int i = 0; i < static_cast<int>(poses_.size()); ++i) {
      const Eigen::Vector2d f = spot(x, poses_[i].first);
      r.segment<2>(2 * i) = f - poses_[i].second;
      for (int k = 0; k < 11; ++k) {
        Vector11 xp = x;
        const double h = 1e-6 * s[k] * 1e3;
        xp[k] += h;
        j.block<2, 1>(2 * i, k) = (spot(xp, poses_[i].first) - f) / h;
      }
    }
    // The prior: each unknown near nominal within its spread; weak, so the data win once they
    // determine an unknown. Readings are weighted as 0.1 mm, far above their noise, which keeps
    // the prior relevant only where the data say nothing.
    constexpr double kReadingMm = 0.1;
    j.topRows(m) /= kReadingMm;
    r.head(m) /= kReadingMm;
    j.bottomRows(11) = s.cwiseInverse().asDiagonal();
    r.tail(11) = x.cwiseQuotient(s);
    const Vector11 step = -(j.transpose() * j).ldlt().solve(j.transpose() * r);
    x += step;
    if (step.cwiseQuotient(s).norm() < 1e-6) break;
  }
  x_ = x;
}

}  // namespace zerocal::servo
