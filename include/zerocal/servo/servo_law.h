// The fine servo's control law, as a policy the servo loop calls (the way libfranka's control
// loop takes its motion callback): the loop owns the robot, the readings, the stop tests, the
// step limit and the fault; the law only turns the spot's error into a joint correction.
//
// Per fine-servo cycle the loop calls, in this order:
//   start(J)                  once, at the acquired pose, with the model's image Jacobian there
//   correction(e, valid)      for each reading that steers; e = spot - target (mm, PSD frame)
//   moved(dq)                 after the move it sent: the correction as limited and commanded
//   held()                    when it read again without a move (settling) instead
// A law runs inside the servo cycle: it must not allocate, lock, log or throw.
#pragma once

#include <Eigen/Core>

#include "zerocal/model/robot.h"

namespace zerocal::servo {

using ImageJacobian = Eigen::Matrix<double, 2, kJointCount>;  // mm per deg
using JointStep = Eigen::Matrix<double, kJointCount, 1>;      // deg

// Minimum-norm pseudo-inverse of J with a Tikhonov term: J^T (J J^T + damping I)^-1.
Eigen::Matrix<double, kJointCount, 2> dampedPseudoInverse(const ImageJacobian& j,
                                                          double damping) noexcept;

class ServoLaw {
 public:
  virtual ~ServoLaw() = default;
  virtual void start(const ImageJacobian& j) noexcept = 0;
  // The joint change (deg) wanted for error `e` (mm); `valid`: the reading is in the map's zone
  // (outside it the spot's coordinates are the chain's coarse estimate). The loop scales it down
  // to its step limit before sending it.
  virtual JointStep correction(const Eigen::Vector2d& e, bool valid) noexcept = 0;
  virtual void moved(const JointStep& dq) noexcept = 0;
  virtual void held() noexcept = 0;
};

// The default law (servo.h explains it): dq = -gain (A J)^+ e, with the 2 x 2 A fitted online to
// the observed motion of every move between two readings in the valid zone,
//
//   A = (sum de p^T + w^2 I) (sum p p^T + w^2 I)^-1,  p = J dq,  w = prior_mm.
class CorrectedJacobianLaw final : public ServoLaw {
 public:
  struct Options {
    double gain = 0.9;         // (0, 1]
    double damping_mm = 1e-3;  // Tikhonov term of the pseudo-inverse, (mm/deg)^2 scale
    bool correct = true;       // fit A; false: A = I throughout
    double prior_mm = 0.3;     // w: the motion that weighs as much as the model
  };
  explicit CorrectedJacobianLaw(const Options& options) : options_(options) {}

  void start(const ImageJacobian& j) noexcept override;
  JointStep correction(const Eigen::Vector2d& e, bool valid) noexcept override;
  void moved(const JointStep& dq) noexcept override;
  void held() noexcept override { have_previous_ = false; }

  // The current A (I until the observed motion outweighs the prior).
  const Eigen::Matrix2d& correctionMatrix() const noexcept { return correction_; }

 private:
  Options options_;
  ImageJacobian j_ = ImageJacobian::Zero();
  Eigen::Matrix2d motion_moments_ = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d observed_moments_ = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d correction_ = Eigen::Matrix2d::Identity();
  bool have_previous_ = false;  // a move between the previous steering reading and the next
  bool previous_valid_ = false;
  Eigen::Vector2d e_previous_ = Eigen::Vector2d::Zero();
  JointStep dq_previous_ = JointStep::Zero();
};

}  // namespace zerocal::servo
