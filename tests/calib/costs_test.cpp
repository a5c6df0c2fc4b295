// Every cost functor's analytic (automatic) derivatives against numeric ones.
#include "costs.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <memory>

#include "stored_plan.h"
#include "zerocal/calib/experiment.h"

namespace zerocal {
namespace {

class CostGradients : public ::testing::Test {
 protected:
  Table2Scenario sc = table2Scenario();
  // A point away from the nominal so that no derivative vanishes by symmetry.
  Eigen::Vector4d delta{0.01, -0.02, 0.015, -0.01};
  Eigen::Vector4d laser{0.01, -0.02, 0.5, -0.3};
  Eigen::Vector3d target{905, -48, 401};
  std::vector<Pose> poses = testing::storedPlan("table2-8");  // the optimal planner's

  void check(const ceres::CostFunction& cost, std::vector<const double*> params) {
    ceres::NumericDiffOptions numeric;
    // The pairwise cost bends sharply along near-parallel pairs: start Ridders with small steps.
    numeric.ridders_relative_initial_step_size = 1e-4;
    ceres::GradientChecker checker(
        &cost, static_cast<const std::vector<const ceres::Manifold*>*>(nullptr), numeric);
    ceres::GradientChecker::ProbeResults results;
    checker.Probe(params.data(), 1e-7, &results);
    // Ceres' own verdict divides by the entry, which fails on entries that are zero up to
    // rounding; judge each block's error against the block's scale instead.
    ASSERT_EQ(results.jacobians.size(), params.size());
    for (std::size_t b = 0; b < params.size(); ++b) {
      const Eigen::MatrixXd diff = results.jacobians[b] - results.numeric_jacobians[b];
      const double scale = std::max(1.0, results.numeric_jacobians[b].cwiseAbs().maxCoeff());
      EXPECT_LT(diff.cwiseAbs().maxCoeff() / scale, 1e-7) << "block " << b << "\n"
                                                          << results.error_log;
    }
  }
};

TEST_F(CostGradients, PointToLineWithoutReading) {
  for (const auto& pose : poses) {
    std::unique_ptr<ceres::CostFunction> cost(
        PointToLineCost::create(sc.cell, pose.q_deg, Eigen::Vector3d::Zero(), 0.03));
    check(*cost, {delta.data(), laser.data(), target.data()});
  }
}

TEST_F(CostGradients, PointToLineWithHitPointOffset) {
  std::unique_ptr<ceres::CostFunction> cost(
      PointToLineCost::create(sc.cell, poses[3].q_deg, Eigen::Vector3d(0.4, -0.3, 0.0), 0.03));
  check(*cost, {delta.data(), laser.data(), target.data()});
}

TEST_F(CostGradients, PointToLineWithLinkErrorsAndCompliance) {
  ASSERT_TRUE(sc.cell.robot.hasGravityModel());  // the shipped robot's: the torque is not zero
  Eigen::Matrix<double, kLinkParameterCount, 1> link;
  for (int k = 0; k < kLinkParameterCount; ++k)
    link[k] = (k % 3 == 2 ? 1e-4 : 0.1) * (k % 2 ? -1 : 1);
  const Eigen::Vector2d compliance(2e-4, -1e-4);  // rad per kN m
  for (const auto& pose : poses) {
    std::unique_ptr<ceres::CostFunction> cost(
        LinkPointToLineCost::create(sc.cell, pose.q_deg, Eigen::Vector3d(0.2, 0.1, 0), 0.03));
    check(*cost, {delta.data(), laser.data(), link.data(), compliance.data(), target.data()});
  }
}

// The compliance turns joint j by c_j tau_j(q): the same residual as the offset turned so.
TEST_F(CostGradients, ComplianceActsAsTheTorqueTimesItOnTheJoint) {
  const Eigen::Matrix<double, kLinkParameterCount, 1> zero_link =
      Eigen::Matrix<double, kLinkParameterCount, 1>::Zero();
  const Eigen::Vector2d compliance(3e-4, -2e-4);
  for (const auto& pose : poses) {
    const auto torque = gravityTorqueKnm(sc.cell.robot, sc.cell.robot.masses, pose.q_deg);
    EXPECT_GT(std::abs(torque[0]), 1e-3);
    Eigen::Vector4d turned = delta;
    turned[0] += compliance[0] * torque[0];
    turned[1] += compliance[1] * torque[1];
    double expected[2], with[2];
    PointToLineCost(sc.cell, pose.q_deg, Eigen::Vector3d::Zero(), 0.03)(turned.data(), laser.data(),
                                                                        target.data(), expected);
    LinkPointToLineCost(sc.cell, pose.q_deg, Eigen::Vector3d::Zero(), 0.03)(
        delta.data(), laser.data(), zero_link.data(), compliance.data(), target.data(), with);
    EXPECT_NEAR(expected[0], with[0], 1e-9);
    EXPECT_NEAR(expected[1], with[1], 1e-9);
  }
}

TEST_F(CostGradients, LinkErrorsOfZeroGiveThePointToLineResidual) {
  const Eigen::Matrix<double, kLinkParameterCount, 1> zero =
      Eigen::Matrix<double, kLinkParameterCount, 1>::Zero();
  for (const auto& pose : poses) {
    const Eigen::Vector3d offset(0.2, 0.1, 0);
    double plain[2], with_links[2];
    PointToLineCost(sc.cell, pose.q_deg, offset, 0.03)(delta.data(), laser.data(), target.data(),
                                                       plain);
    const Eigen::Vector2d no_compliance = Eigen::Vector2d::Zero();
    LinkPointToLineCost(sc.cell, pose.q_deg, offset, 0.03)(
        delta.data(), laser.data(), zero.data(), no_compliance.data(), target.data(), with_links);
    EXPECT_NEAR(plain[0], with_links[0], 1e-9);
    EXPECT_NEAR(plain[1], with_links[1], 1e-9);
  }
}

TEST_F(CostGradients, Pairwise) {
  std::unique_ptr<ceres::CostFunction> cost(PairwiseCost::create(sc.cell, poses, 0.03));
  check(*cost, {delta.data(), laser.data()});
}

TEST_F(CostGradients, PointToLineResidualIsTheMissDistance) {
  // A line through the target has zero residual; moving the target 1 mm across the beam gives
  // a 1 mm miss (sigma 1).
  CalibrationParameters p;
  p.target_mm = sc.truth.target_mm;
  const Line l = laserLine(sc.cell, poses[0].q_deg, p);
  const Eigen::Vector3d across = l.direction.unitOrthogonal();
  PointToLineCost functor(sc.cell, poses[0].q_deg, Eigen::Vector3d::Zero(), 1.0);
  const Eigen::Vector3d on_line = l.point + 500 * l.direction;
  double r[2];
  functor(p.delta_rad.data(), p.laser.data(), on_line.data(), r);
  EXPECT_NEAR(std::hypot(r[0], r[1]), 0.0, 1e-9);
  const Eigen::Vector3d off = on_line + across;
  functor(p.delta_rad.data(), p.laser.data(), off.data(), r);
  EXPECT_NEAR(std::hypot(r[0], r[1]), 1.0, 1e-9);
}

}  // namespace
}  // namespace zerocal
