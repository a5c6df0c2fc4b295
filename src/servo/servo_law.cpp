#include "zerocal/servo/servo_law.h"

#include <Eigen/Dense>

namespace zerocal::servo {

Eigen::Matrix<double, kJointCount, 2> dampedPseudoInverse(const ImageJacobian& j,
                                                          double damping) noexcept {
  const Eigen::Matrix2d jjt = j * j.transpose() + damping * Eigen::Matrix2d::Identity();
  return j.transpose() * jjt.inverse();
}

void CorrectedJacobianLaw::start(const ImageJacobian& j) noexcept {
  j_ = j;
  // Both moments start at w^2 I, so A = I until the observed motion outweighs the prior.
  motion_moments_ = options_.prior_mm * options_.prior_mm * Eigen::Matrix2d::Identity();
  observed_moments_ = motion_moments_;
  correction_ = Eigen::Matrix2d::Identity();
  have_previous_ = previous_valid_ = false;
  e_previous_ = Eigen::Vector2d::Zero();
  dq_previous_ = JointStep::Zero();
}

JointStep CorrectedJacobianLaw::correction(const Eigen::Vector2d& e, bool valid) noexcept {
  // Only a move between two readings in the zone says how the spot really moves: outside it the
  // coarse estimate's scale is not the map's.
  if (options_.correct && have_previous_ && previous_valid_ && valid) {
    const Eigen::Vector2d predicted = j_ * dq_previous_;
    motion_moments_ += predicted * predicted.transpose();
    observed_moments_ += (e - e_previous_) * predicted.transpose();
    correction_ = observed_moments_ * motion_moments_.inverse();
  }
  const ImageJacobian steer = correction_ * j_;
  e_previous_ = e;
  previous_valid_ = valid;
  return -options_.gain * (dampedPseudoInverse(steer, options_.damping_mm) * e);
}

void CorrectedJacobianLaw::moved(const JointStep& dq) noexcept {
  dq_previous_ = dq;
  have_previous_ = true;
}

}  // namespace zerocal::servo
