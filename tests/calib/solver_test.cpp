#include "zerocal/calib/solver.h"

#include <gtest/gtest.h>

#include "zerocal/calib/experiment.h"
#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace {

std::vector<Pose> plan(const Table2Scenario& sc, Pattern pattern, int n = 8) {
  PlanOptions o;
  o.pattern = pattern;
  o.poses = n;
  return planPoses(sc.cell, sc.truth.target_mm, o).poses;
}

class NoiseFreeRoundTrip : public ::testing::TestWithParam<Pattern> {};

TEST_P(NoiseFreeRoundTrip, RecoversTruthTo1e6Degrees) {
  Table2Scenario sc = table2Scenario();
  sc.truth.laser = Eigen::Vector4d(0.004, -0.003, 0.7, -0.4);  // an uncalibrated laser too
  std::mt19937_64 rng(7);
  const auto recorded = simulateRecording(sc.cell, sc.truth, plan(sc, GetParam()), 0.0, rng);
  SolveOptions options;
  options.noise_mm = 0.03;
  const SolveReport r = solve(sc.cell, recorded, options);
  ASSERT_TRUE(r.converged) << r.message;
  for (int k = 0; k < kOffsetCount; ++k) {
    EXPECT_TRUE(r.parameters[k].identifiable) << r.parameters[k].reason;
    EXPECT_NEAR(r.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 1e-6) << k;
  }
  for (int k = 0; k < kLaserParamCount; ++k)
    EXPECT_NEAR(r.estimate.laser[k], sc.truth.laser[k], 1e-6) << k;
  EXPECT_TRUE(r.estimate.target_mm.isApprox(sc.truth.target_mm, 1e-9));
  EXPECT_LT(r.rms_miss_mm, 1e-6);
  EXPECT_EQ(r.rank, kUnknownCount);
}

INSTANTIATE_TEST_SUITE_P(Plans, NoiseFreeRoundTrip,
                         ::testing::Values(Pattern::kI, Pattern::kOptimal, Pattern::kMixed));

TEST(Solver, NoisyResultLiesWithinItsOwnIntervals) {
  // Over a few seeds the truth falls inside 3 reported sigma, and chi2/dof is plausible.
  const Table2Scenario sc = table2Scenario();
  const auto planned = plan(sc, Pattern::kOptimal, 12);
  const double sigma = sc.half_width_mm / std::sqrt(3.0);
  double chi2 = 0;
  int dof = 0;
  for (int seed = 1; seed <= 5; ++seed) {
    std::mt19937_64 rng(seed);
    const auto recorded = simulateRecording(sc.cell, sc.truth, planned, sc.half_width_mm, rng);
    SolveOptions options;
    options.noise_mm = sigma;
    const SolveReport r = solve(sc.cell, recorded, options);
    ASSERT_TRUE(r.converged);
    for (int k = 0; k < kOffsetCount; ++k) {
      const double err = r.parameters[k].value - sc.truth.delta_rad[k] * kRadToDeg;
      EXPECT_LT(std::abs(err), 3.5 * r.parameters[k].sigma) << "seed " << seed << " k " << k;
      EXPECT_GT(r.parameters[k].sigma, 0.0);
      EXPECT_LT(r.parameters[k].ci95_low, r.parameters[k].value);
    }
    chi2 += *r.chi2_per_dof * r.dof;
    dof += r.dof;
  }
  EXPECT_GT(chi2 / dof, 0.5);
  EXPECT_LT(chi2 / dof, 1.6);
}

TEST(Solver, EstimatesNoiseWhenNotGiven) {
  const Table2Scenario sc = table2Scenario();
  std::mt19937_64 rng(3);
  const auto recorded =
      simulateRecording(sc.cell, sc.truth, plan(sc, Pattern::kOptimal, 40), 0.05, rng);
  const SolveReport r = solve(sc.cell, recorded);
  EXPECT_TRUE(r.noise_estimated);
  EXPECT_FALSE(r.chi2_per_dof.has_value());
  EXPECT_NEAR(r.noise_mm, 0.05 / std::sqrt(3.0), 0.01);
}

TEST(Solver, FlagsAnOutlierAndRobustLossResistsIt) {
  const Table2Scenario sc = table2Scenario();
  std::mt19937_64 rng(11);
  auto recorded = simulateRecording(sc.cell, sc.truth, plan(sc, Pattern::kOptimal, 16), 0.01, rng);
  recorded[5].q_deg[3] += 0.05;  // a pose recorded while the wrist was still moving
  SolveOptions options;
  options.noise_mm = 0.01 / std::sqrt(3.0);
  const SolveReport plain = solve(sc.cell, recorded, options);
  int flagged = 0;
  for (const auto& p : plain.poses) flagged += p.outlier ? 1 : 0;
  EXPECT_GE(flagged, 1);
  options.loss = RobustLoss::kCauchy;
  const SolveReport robust = solve(sc.cell, recorded, options);
  EXPECT_TRUE(robust.poses[5].outlier);
  double plain_err = 0, robust_err = 0;
  for (int k = 0; k < kOffsetCount; ++k) {
    plain_err += std::abs(plain.estimate.delta_rad[k] - sc.truth.delta_rad[k]);
    robust_err += std::abs(robust.estimate.delta_rad[k] - sc.truth.delta_rad[k]);
  }
  EXPECT_LT(robust_err, plain_err);
}

TEST(Solver, HitPointModelUsesTheReadings) {
  // The spot was recorded away from the PSD centre; with the readings the solve is exact,
  // without them it is not.
  Table2Scenario sc = table2Scenario();
  sc.cell.psd_rotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                         Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const auto planned = plan(sc, Pattern::kOptimal, 10);
  std::vector<Pose> recorded;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uv(-0.5, 0.5);
  for (const auto& p : planned) {
    Pose rec;
    rec.psd_uv_mm = Eigen::Vector2d(uv(rng), uv(rng));
    const Eigen::Vector3d hit = sc.truth.target_mm +
                                sc.cell.psd_rotation.col(0) * rec.psd_uv_mm->x() +
                                sc.cell.psd_rotation.col(1) * rec.psd_uv_mm->y();
    rec.q_deg = *servoOnto(sc.cell, sc.truth, hit, p.q_deg);
    recorded.push_back(rec);
  }
  SolveOptions options;
  options.noise_mm = 0.002;
  const SolveReport with = solve(sc.cell, recorded, options);
  EXPECT_TRUE(with.used_readings);
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(with.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 1e-6);
  options.use_readings = false;
  const SolveReport without = solve(sc.cell, recorded, options);
  EXPECT_FALSE(without.used_readings);
  EXPECT_GT(without.rms_miss_mm, 0.05);
}

TEST(Solver, PairwiseCostSolvesNoiseFreeDataAndReportsUncertainty) {
  const Table2Scenario sc = table2Scenario();
  std::mt19937_64 rng(1);
  const auto recorded = simulateRecording(sc.cell, sc.truth, plan(sc, Pattern::kI), 0.0, rng);
  SolveOptions options;
  options.cost = CostKind::kPairwise;
  options.noise_mm = 0.03;
  const SolveReport r = solve(sc.cell, recorded, options);
  for (int k = 0; k < kOffsetCount; ++k) {
    EXPECT_NEAR(r.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 1e-5);
    EXPECT_TRUE(std::isfinite(r.parameters[k].sigma));
    EXPECT_GT(r.parameters[k].sigma, 0);
  }
}

TEST(Solver, RefusesTooFewPosesNamingTheMinimum) {
  const Table2Scenario sc = table2Scenario();
  auto poses = plan(sc, Pattern::kI);
  poses.resize(5);
  try {
    solve(sc.cell, poses);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("at least 6"), std::string::npos) << e.what();
  }
}

TEST(Solver, RefusesJointsOutsideLimitsNamingTheLine) {
  const Table2Scenario sc = table2Scenario();
  auto poses = plan(sc, Pattern::kI);
  poses[2].q_deg[4] = 130;
  poses[2].source_line = 5;
  try {
    solve(sc.cell, poses);
    FAIL();
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("line 5"), std::string::npos) << what;
    EXPECT_NE(what.find("joint 5 = 130"), std::string::npos) << what;
  }
}

TEST(Solver, CancelStopsTheSolve) {
  const Table2Scenario sc = table2Scenario();
  std::mt19937_64 rng(1);
  const auto recorded = simulateRecording(sc.cell, sc.truth, plan(sc, Pattern::kI), 0.05, rng);
  SolveOptions options;
  options.cancelled = [] { return true; };
  const SolveReport r = solve(sc.cell, recorded, options);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.message, "cancelled");
}

}  // namespace
}  // namespace zerocal

namespace zerocal {
namespace {

TEST(Solver, AnyStandardDhArmWorks) {
  // A UR5-like arm (different geometry, alpha signs, negative link lengths) with the laser along
  // the flange z-axis, offset from it: plan, record, solve, recover the truth.
  const Robot ur = parseRobot(R"(
name: UR5-like
joints:
  - {a_mm: 0, alpha_deg: 90, d_mm: 89.159, theta_offset_deg: 0, lower_deg: -360, upper_deg: 360, max_speed_deg_s: 180}
  - {a_mm: -425, alpha_deg: 0, d_mm: 0, theta_offset_deg: 0, lower_deg: -360, upper_deg: 360, max_speed_deg_s: 180}
  - {a_mm: -392.25, alpha_deg: 0, d_mm: 0, theta_offset_deg: 0, lower_deg: -360, upper_deg: 360, max_speed_deg_s: 180}
  - {a_mm: 0, alpha_deg: 90, d_mm: 109.15, theta_offset_deg: 0, lower_deg: -360, upper_deg: 360, max_speed_deg_s: 180}
  - {a_mm: 0, alpha_deg: -90, d_mm: 94.65, theta_offset_deg: 0, lower_deg: -360, upper_deg: 360, max_speed_deg_s: 180}
  - {a_mm: 0, alpha_deg: 0, d_mm: 82.3, theta_offset_deg: 0, lower_deg: -360, upper_deg: 360, max_speed_deg_s: 180}
)",
                              "ur5.yaml");
  const CellModel cell{ur, LaserModel(Eigen::Vector3d::UnitZ(), Eigen::Vector3d(10, 0, 20)),
                       Eigen::Matrix3d::Identity()};
  CalibrationParameters truth;
  truth.delta_rad = Eigen::Vector4d(0.3, -0.2, 0.5, -0.4) * kDegToRad;
  truth.laser = Eigen::Vector4d(0.002, -0.001, 0.3, 0.2);
  truth.target_mm = Eigen::Vector3d(400, -100, 0);
  PlanOptions o;
  o.standoff_min_mm = 150;
  o.standoff_max_mm = 400;
  const Plan plan = planPoses(cell, truth.target_mm, o);
  EXPECT_EQ(plan.prediction.rank, kUnknownCount);
  std::mt19937_64 rng(1);
  const auto recorded = simulateRecording(cell, truth, plan.poses, 0.0, rng);
  SolveOptions so;
  so.noise_mm = 0.01;
  const SolveReport r = solve(cell, recorded, so);
  ASSERT_TRUE(r.converged);
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(r.parameters[k].value, truth.delta_rad[k] * kRadToDeg, 1e-6);
  for (int k = 0; k < kLaserParamCount; ++k) EXPECT_NEAR(r.estimate.laser[k], truth.laser[k], 1e-6);
}

}  // namespace
}  // namespace zerocal
