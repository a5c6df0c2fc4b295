// The per-pose noise model (MissNoise): each pose's covariance at the detector is what the joints'
// repeatability and the PSD's noise do to its miss, and its weight whitens it.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <iostream>
#include <random>

#include "costs.h"
#include "stored_plan.h"
#include "zerocal/calib/experiment.h"
#include "zerocal/calib/solver.h"

namespace zerocal {
namespace {

class NoiseModel : public ::testing::Test {
 protected:
  NoiseModel() {
    cell.noise = {1.5e-3, 0.001};
    for (const Pose& pose : poses) {
      // The hit point where the pose's nominal line meets a plane 450 mm from the laser.
      const Line line = laserLine(cell, pose.q_deg, at);
      targets.push_back(line.point + 450 * line.direction);
    }
  }
  CellModel cell = table2Scenario().cell;
  CalibrationParameters at;
  std::vector<Pose> poses = testing::storedPlan("table2-8");
  std::vector<Eigen::Vector3d> targets;

  CalibrationParameters atPose(std::size_t i) const {
    CalibrationParameters p = at;
    p.target_mm = targets[i];
    return p;
  }
  // The miss of pose i's line from its hit point when the arm stands at q + dq (deg).
  Eigen::Vector2d missAt(std::size_t i, const Joints& dq) const {
    Joints q = poses[i].q_deg;
    for (int j = 0; j < kJointCount; ++j) q[j] += dq[j];
    const PointToLineCost cost(cell, q, Eigen::Vector3d::Zero(), 1.0);
    const CalibrationParameters p = atPose(i);
    Eigen::Vector2d r;
    cost(p.delta_rad.data(), p.laser.data(), p.target_mm.data(), r.data());
    return r;
  }
};

TEST_F(NoiseModel, EachPoseCovarianceIsWhatItsJointsRepeatabilityDoesToItsMiss) {
  // Monte Carlo of the arm's repeatability (the simulated arm's: every joint, normal, 1.5e-3
  // deg) against the model's linearised covariance, pose by pose; readings off (no PSD part).
  CellModel joints_only = cell;
  joints_only.noise.psd_mm = 0;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, cell.noise.joint_repeatability_deg);
  constexpr int kDraws = 20000;
  double smallest = 1e9, largest = 0, most_anisotropic = 1;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    Eigen::Matrix2d sample = Eigen::Matrix2d::Zero();
    const Eigen::Vector2d centre = missAt(i, Joints{});
    for (int k = 0; k < kDraws; ++k) {
      Joints dq;
      for (double& e : dq) e = normal(rng);
      const Eigen::Vector2d d = missAt(i, dq) - centre;
      sample += d * d.transpose() / kDraws;
    }
    const Eigen::Matrix2d model = missCovariance(joints_only, poses[i], atPose(i), false, 0);
    // Sampling error of a variance from 20000 draws: about 1 %; 4 % is far beyond it.
    EXPECT_NEAR(sample.trace(), model.trace(), 0.04 * model.trace()) << "pose " << i + 1;
    EXPECT_LT((sample - model).norm(), 0.05 * model.norm()) << "pose " << i + 1;
    const double per_axis = std::sqrt(model.trace() / 2);
    smallest = std::min(smallest, per_axis);
    largest = std::max(largest, per_axis);
    const Eigen::Vector2d axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(model).eigenvalues();
    most_anisotropic = std::max(most_anisotropic, std::sqrt(axes[1] / axes[0]));
  }
  // Not one sigma for every pose, nor for every direction: why each is weighed by its own.
  std::cout << "per-pose sigma " << smallest << " .. " << largest << " mm per axis, axis ratio up to "
            << most_anisotropic << "\n";
  EXPECT_GT(largest / smallest, 1.2) << smallest << " .. " << largest << " mm";
  EXPECT_GT(most_anisotropic, 1.1);
}

TEST_F(NoiseModel, TheWeightWhitensEachPoseToTheReferenceSigma) {
  const double ref = cell.noise.referenceMm();
  EXPECT_NEAR(ref, std::hypot(1.5e-3 * kDegToRad * 1000, 0.001), 1e-12);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Matrix2d sigma = missCovariance(cell, poses[i], atPose(i), false, 0);
    const Eigen::Matrix2d w = missWeight(cell, poses[i], atPose(i), false);
    EXPECT_LT((w * sigma * w.transpose() - ref * ref * Eigen::Matrix2d::Identity()).norm(),
              1e-9 * ref * ref)
        << "pose " << i + 1;
  }
}

TEST_F(NoiseModel, WithoutAPerPoseModelEveryPoseHasTheGivenSigma) {
  const CellModel plain = atDetector(cell);
  EXPECT_FALSE(plain.noise.perPose());
  EXPECT_EQ(missWeight(plain, poses[0], atPose(0), false), Eigen::Matrix2d::Identity());
  EXPECT_EQ(missCovariance(plain, poses[0], atPose(0), false, 0.02),
            0.0004 * Eigen::Matrix2d::Identity());
  SolveOptions given;
  given.noise_mm = 0.02;
  EXPECT_EQ(*withCellNoise(plain, given).noise_mm, 0.02);
  EXPECT_EQ(*withCellNoise(cell, given).noise_mm, cell.noise.referenceMm());
}

}  // namespace
}  // namespace zerocal
