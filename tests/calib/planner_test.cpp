#include "zerocal/calib/planner.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "zerocal/calib/experiment.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/calib/sensitivity.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

TEST(AimLaser, PutsTheNominalBeamThroughTheTarget) {
  const Table2Scenario sc = table2Scenario();
  const Eigen::Vector3d beam = Eigen::Vector3d(0.3, -0.2, -1).normalized();
  const auto q = aimLaser(sc.cell, sc.truth.target_mm, beam, 550, Joints{-3, 10, 0, 0, 45, 0}, 5);
  ASSERT_TRUE(q.has_value());
  const Line l = laserLine(sc.cell, *q, CalibrationParameters{});
  EXPECT_TRUE(l.direction.isApprox(beam, 1e-9));
  EXPECT_TRUE((l.point + 550 * l.direction).isApprox(sc.truth.target_mm, 1e-9));
  EXPECT_TRUE(sc.cell.robot.withinLimits(*q, 5));
}

TEST(AimLaser, UnreachableTargetGivesNothing) {
  const Table2Scenario sc = table2Scenario();
  EXPECT_FALSE(aimLaser(sc.cell, Eigen::Vector3d(5000, 0, 400), Eigen::Vector3d(0, 0, -1), 500,
                        Joints{0, 10, 0, 0, 45, 0}, 5)
                   .has_value());
}

TEST(Planner, PatternsHaveTheirDefiningGeometry) {
  const Table2Scenario sc = table2Scenario();
  PlanOptions o;
  o.pattern = Pattern::kI;
  const Plan one = planPoses(sc.cell, sc.truth.target_mm, o);
  o.pattern = Pattern::kII;
  const Plan two = planPoses(sc.cell, sc.truth.target_mm, o);
  auto span = [](const Plan& p, int j) {
    double lo = 1e9, hi = -1e9;
    for (const auto& pose : p.poses)
      lo = std::min(lo, pose.q_deg[j]), hi = std::max(hi, pose.q_deg[j]);
    return hi - lo;
  };
  ASSERT_EQ(one.poses.size(), 8u);
  ASSERT_EQ(two.poses.size(), 8u);
  EXPECT_GT(span(one, 0), 20.0);  // joint 1 changes a lot in pattern I
  EXPECT_LT(span(two, 0), 8.0);   // and little in pattern II
  // Stand-offs vary in both (the second trap).
  const auto s = standoffs(
      sc.cell, one.poses,
      CalibrationParameters{Eigen::Vector4d::Zero(), Eigen::Vector4d::Zero(), sc.truth.target_mm});
  EXPECT_GT(*std::max_element(s.begin(), s.end()) - *std::min_element(s.begin(), s.end()), 200);
  // Pattern II predicts a far worse delta2 than pattern I: the paper's finding.
  EXPECT_TRUE(!two.prediction.identifiable[0] ||
              two.prediction.sigma[0] > 5 * one.prediction.sigma[0]);
}

TEST(Planner, EveryPlannedPoseRespectsTheMarginAndAimsAtTheTarget) {
  const Table2Scenario sc = table2Scenario();
  for (Pattern p : {Pattern::kI, Pattern::kII, Pattern::kMixed, Pattern::kOptimal}) {
    PlanOptions o;
    o.pattern = p;
    o.poses = 10;
    o.margin_deg = 8;
    const Plan plan = planPoses(sc.cell, sc.truth.target_mm, o);
    ASSERT_EQ(plan.poses.size(), 10u) << patternName(p);
    for (const auto& pose : plan.poses) {
      EXPECT_TRUE(sc.cell.robot.withinLimits(pose.q_deg, 8)) << patternName(p);
      const Line l = laserLine(sc.cell, pose.q_deg, CalibrationParameters{});
      const Eigen::Vector3d w = sc.truth.target_mm - l.point;
      EXPECT_LT((w - w.dot(l.direction) * l.direction).norm(), 1e-6);
      EXPECT_GE(w.dot(l.direction), o.standoff_min_mm - 1e-6);
      EXPECT_LE(w.dot(l.direction), o.standoff_max_mm + 1e-6);
    }
  }
}

TEST(Planner, RejectsBadOptions) {
  const Table2Scenario sc = table2Scenario();
  PlanOptions o;
  o.poses = 4;
  EXPECT_THROW(planPoses(sc.cell, sc.truth.target_mm, o), InputError);
  o = PlanOptions{};
  o.standoff_min_mm = 900;
  o.standoff_max_mm = 100;
  EXPECT_THROW(planPoses(sc.cell, sc.truth.target_mm, o), InputError);
  EXPECT_THROW(parsePattern("III"), InputError);
  EXPECT_EQ(parsePattern("ii"), Pattern::kII);
  // A target out of reach.
  EXPECT_THROW(planPoses(sc.cell, Eigen::Vector3d(4000, 0, 0), PlanOptions{}), InputError);
}

// A travel time for the tests: the joint that moves most, at 100 deg/s (any metric will do).
double jointTravelS(const Joints& from, const Joints& to) {
  double most = 0;
  for (int i = 0; i < kJointCount; ++i) most = std::max(most, std::abs(to[i] - from[i]));
  return most / 100.0;
}

TEST(Planner, VisitsThePosesInTheOrderOfLeastTravel) {
  const Table2Scenario sc = table2Scenario();
  PlanOptions o;
  o.poses = 16;
  const Plan chosen = planPoses(sc.cell, sc.truth.target_mm, o);
  o.travel_s = jointTravelS;
  const Plan ordered = planPoses(sc.cell, sc.truth.target_mm, o);
  // The same poses, so the same prediction; only their order differs.
  ASSERT_EQ(ordered.poses.size(), chosen.poses.size());
  EXPECT_TRUE(std::is_permutation(ordered.poses.begin(), ordered.poses.end(), chosen.poses.begin(),
                                  [](const Pose& a, const Pose& b) { return a.q_deg == b.q_deg; }));
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(ordered.prediction.sigma[k], chosen.prediction.sigma[k],
                1e-9 * chosen.prediction.sigma[k]);
  const double before = tourSeconds(chosen.poses, jointTravelS);
  const double after = tourSeconds(ordered.poses, jointTravelS);
  EXPECT_LT(after, 0.8 * before) << before << " s in the chosen order";
  // No reversal of a stretch of the tour shortens it.
  for (std::size_t i = 0; i + 1 < ordered.poses.size(); ++i)
    for (std::size_t j = i + 1; j < ordered.poses.size(); ++j) {
      std::vector<Pose> other = ordered.poses;
      std::reverse(other.begin() + i, other.begin() + j + 1);
      EXPECT_GE(tourSeconds(other, jointTravelS), after - 1e-9) << i << ".." << j;
    }
}

TEST(Planner, OrderForTravelFindsTheShortestTourOfAFewPoses) {
  const Table2Scenario sc = table2Scenario();
  const std::vector<Pose> planned = planPoses(sc.cell, sc.truth.target_mm, PlanOptions{}).poses;
  std::vector<Pose> few(planned.begin(), planned.begin() + 7);
  std::vector<int> order(few.size());
  std::iota(order.begin(), order.end(), 0);
  double shortest = std::numeric_limits<double>::infinity();
  do {
    std::vector<Pose> tour;
    for (int k : order) tour.push_back(few[k]);
    shortest = std::min(shortest, tourSeconds(tour, jointTravelS));
  } while (std::next_permutation(order.begin(), order.end()));
  orderForTravel(few, jointTravelS);
  EXPECT_NEAR(tourSeconds(few, jointTravelS), shortest, 1e-9);
}

TEST(Sensitivity, WristRotationAt600MmMatchesThePaper) {
  // Paper III-E: with about 600 mm from laser to PSD, 0.02 mm on the PSD is about 0.002 deg.
  const Table2Scenario sc = table2Scenario();
  const auto q = aimLaser(sc.cell, sc.truth.target_mm, Eigen::Vector3d(0, 0, -1), 600,
                          Joints{-3, 10, 0, 0, 45, 0}, 5);
  ASSERT_TRUE(q.has_value());
  const auto s = spotSensitivity(sc.cell, *q, 600);
  // Rotating about any joint axis moves the spot by (distance from the axis) x angle; for the
  // wrist that distance is about the stand-off.
  EXPECT_NEAR(s[4].deg_per_20um, 0.02 / (600 * kDegToRad), 0.0006);
  for (const auto& j : s) EXPECT_GT(j.magnitude_mm_per_deg, 0.0);
}

}  // namespace
}  // namespace zerocal
