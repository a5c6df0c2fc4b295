// The facts the report's ABB section states, checked against the model it was computed with
// (../shared/reference/irb1600.md and calibration-math.md are the sources of the claims).
#include <gtest/gtest.h>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/sensitivity.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace {

TEST(ReferenceFacts, PositiveDeltaTurnsTheArmFurtherThanTheControllerBelieves) {
  // "when the controller reports q_i the arm is at q_i + delta_i": the pose with an offset of
  // +0.5 deg on joint 2 is the nominal pose at q2 + 0.5 deg.
  const Robot robot = builtinIrb1600();
  const Joints q{10, 20, -30, 40, 50, 60};
  Joints delta{}, moved = q;
  delta[1] = 0.5;
  moved[1] += 0.5;
  EXPECT_TRUE(flangePoseDeg(robot, q, delta).p.isApprox(flangePoseDeg(robot, moved).p, 1e-12));
}

TEST(ReferenceFacts, JointDirectionsAreTheControllersOnes) {
  // irb1600.md: joint signs equal CJointT's. On an IRB 1600 a positive joint 1 turns the arm
  // anticlockwise seen from above, a positive joint 2 leans the lower arm forward, a positive
  // joint 3 lowers the upper arm, and joint 5 at +90 deg points tool0's z straight down.
  const Robot robot = builtinIrb1600();
  const auto home = flangePoseDeg(robot, Joints{});
  EXPECT_NEAR(home.p.x(), 815, 1e-9);
  EXPECT_NEAR(home.p.z(), 1186.5, 1e-9);
  EXPECT_GT(flangePoseDeg(robot, Joints{30, 0, 0, 0, 0, 0}).p.y(), 400);
  EXPECT_GT(flangePoseDeg(robot, Joints{0, 30, 0, 0, 0, 0}).p.x(), home.p.x() + 200);
  EXPECT_LT(flangePoseDeg(robot, Joints{0, 0, 30, 0, 0, 0}).p.z(), home.p.z() - 300);
  EXPECT_TRUE(flangePoseDeg(robot, Joints{0, 0, 0, 0, 90, 0})
                  .R.col(2)
                  .isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  // Quaternion (w, x, y, z) ~ (0.7071, 0, 0.7071, 0) at q = 0.
  const Eigen::Quaterniond qt(home.R);
  EXPECT_NEAR(std::abs(qt.w()), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(std::abs(qt.y()), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(qt.w() * qt.y(), 0.5, 1e-12);
}

TEST(ReferenceFacts, WristSensitivityIsThePapersFigure) {
  // calibration-math.md section 6: at about 600 mm, 0.02 mm on the PSD is about 0.002 deg of
  // wrist rotation.
  const CellModel cell{builtinIrb1600(), LaserModel(), Eigen::Matrix3d::Identity(), {}};
  const auto s = spotSensitivity(cell, Joints{0, 30, 10, 0, 45, 0}, 600);
  EXPECT_NEAR(s[4].deg_per_20um, 0.002, 0.0002);
}

}  // namespace
}  // namespace zerocal
