// Several PSD placements: the base-parameter analysis, the solve that identifies the link
// errors beside the offsets, and the plan that predicts it.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <string>

#include "stored_plan.h"
#include "zerocal/calib/experiment.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"
#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace {

std::vector<Pose> atPlacement(std::vector<Pose> poses, int placement) {
  for (Pose& p : poses) p.placement = placement;
  return poses;
}

// Three placements spread over the workspace, 10 optimal poses at each (planned once).
const std::vector<Pose>& threePlacementPlan() {
  static const std::vector<Pose> poses = [] {
    const Table2Scenario sc = table2Scenario();
    PlanOptions o;
    o.poses = 10;
    o.more_placements = defaultPlacements(sc.truth.target_mm, 3);
    return planPoses(sc.cell, sc.truth.target_mm, o).poses;
  }();
  return poses;
}

// What a perfect servo records on an arm with the truth's offsets and link errors, at each
// placement's true centre.
std::vector<Pose> record(const CellModel& cell, const CalibrationParameters& truth,
                         const std::vector<Eigen::Vector3d>& centres,
                         const std::vector<Pose>& planned) {
  CellModel arm = cell;
  arm.robot = withLinkErrors(cell.robot, truth.link);
  CalibrationParameters at = truth;
  at.link.setZero();  // in the arm's rows already
  std::vector<Pose> out;
  for (const Pose& p : planned) {
    const auto q = servoOnto(arm, at, centres[p.placement - 1], p.q_deg);
    if (!q) throw std::runtime_error("a pose cannot be servoed");
    Pose rec = p;
    rec.q_deg = *q;
    out.push_back(rec);
  }
  return out;
}

std::vector<Eigen::Vector3d> centresOf(const Table2Scenario& sc) {
  std::vector<Eigen::Vector3d> c{sc.truth.target_mm};
  for (const auto& more : defaultPlacements(sc.truth.target_mm, 3)) c.push_back(more);
  return c;
}

const ParameterEstimate* find(const SolveReport& r, const std::string& name) {
  for (const auto& p : r.parameters)
    if (p.name == name) return &p;
  return nullptr;
}

TEST(BaseParameters, NamesAZeroColumnAndACombinationWithWhatItCombinesWith) {
  const std::vector<Pose> poses = atPlacement(testing::storedPlan("table2-8"), 1);
  const PlacementLayout layout(poses, Robot{}, false);
  const int n = layout.unknownCount();
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd jac(60, n);
  for (int r = 0; r < jac.rows(); ++r)
    for (int c = 0; c < n; ++c) jac(r, c) = normal(rng);
  const int da3 = PlacementLayout::firstLink() + 6, dd4 = PlacementLayout::firstLink() + 10;
  jac.col(da3).setZero();
  jac.col(dd4) = 2 * jac.col(1) - 0.5 * jac.col(layout.firstTarget());
  const BaseParameters base = analyseBaseParameters(jac, layout);
  EXPECT_EQ(base.count, n - 2);
  EXPECT_FALSE(base.identified[da3]);
  EXPECT_EQ(base.reason[da3], "no effect on the measurements at these poses");
  EXPECT_FALSE(base.identified[dd4]);
  EXPECT_NE(base.reason[dd4].find("combined with delta3 and the placement-1 centre"),
            std::string::npos)
      << base.reason[dd4];
  for (int k = 0; k < n; ++k) {
    if (k != da3 && k != dd4) {
      EXPECT_TRUE(base.identified[k]) << layout.name(k);
    }
  }
}

TEST(SeveralPlacements, RecoverTheOffsetsAndTheIdentifiableLinkErrorsWithoutNoise) {
  Table2Scenario sc = table2Scenario();
  sc.truth.laser = Eigen::Vector4d(0.004, -0.003, 0.7, -0.4);
  const std::vector<Pose>& planned = threePlacementPlan();
  ASSERT_EQ(placementCount(planned), 3);
  // The link errors the poses identify: found first, so that the truth is what can be recovered
  // one by one (an unidentifiable error is recovered only as its combination with others).
  const PlacementLayout layout(planned, sc.cell.robot, false);
  const BaseParameters base = analyseBaseParameters(
      placementJacobian(sc.cell, planned, layout, {},
                        placementTargets(sc.cell, planned, layout, {}, false), 1.0, false),
      layout);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  int identified_links = 0;
  for (int l = 0; l < kLinkParameterCount; ++l)
    if (base.identified[PlacementLayout::firstLink() + l]) {
      sc.truth.link[l] = l % 3 == 2 ? 0.01 * kDegToRad * normal(rng) : 0.1 * normal(rng);
      ++identified_links;
    }
  EXPECT_GE(identified_links, 10);
  const auto recorded = record(sc.cell, sc.truth, centresOf(sc), planned);
  SolveOptions options;
  options.noise_mm = 0.01;
  const SolveReport r = solve(sc.cell, recorded, options);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(r.verdict.usable) << ::testing::PrintToString(r.verdict.reasons);
  EXPECT_LT(r.rms_miss_mm, 1e-7);
  ASSERT_EQ(r.parameters.size(), static_cast<std::size_t>(kIdentifiedCount + kLinkParameterCount));
  for (int k = 0; k < kOffsetCount; ++k) {
    EXPECT_TRUE(r.parameters[k].identifiable) << r.parameters[k].reason;
    EXPECT_NEAR(r.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 1e-7) << k;
  }
  for (int k = 0; k < kLaserParamCount; ++k)
    EXPECT_NEAR(r.estimate.laser[k], sc.truth.laser[k], 1e-7) << k;
  for (int l = 0; l < kLinkParameterCount; ++l) {
    const ParameterEstimate& p = r.parameters[kIdentifiedCount + l];
    EXPECT_EQ(p.name, linkParamName(l));
    EXPECT_EQ(p.identifiable, base.identified[PlacementLayout::firstLink() + l]) << p.name;
    const double truth = sc.truth.link[l] * (l % 3 == 2 ? kRadToDeg : 1.0);
    if (p.identifiable) {
      EXPECT_NEAR(p.value, truth, l % 3 == 2 ? 1e-8 : 1e-6) << p.name;
      EXPECT_GT(p.sigma, 0) << p.name;
    }
  }
  ASSERT_EQ(r.placements.size(), 3u);
  const auto centres = centresOf(sc);
  for (int p = 0; p < 3; ++p) {
    EXPECT_EQ(r.placements[p].placement, p + 1);
    EXPECT_EQ(r.placements[p].poses, 10);
    EXPECT_LT((r.placements[p].target_mm - centres[p]).norm(), 1e-6) << p;
  }
}

TEST(SeveralPlacements, EveryLinkErrorOfTheArmLeavesTheOffsetsExact) {
  // Errors on all 18 link parameters: those the poses cannot identify combine with the laser,
  // the centres or the identified ones, never with an offset, so the offsets stay exact up to
  // second-order terms (dd3 is dd2 only while joints 2 and 3 are parallel, which the true twist
  // error dalpha2 breaks: 0.1 mm x 2e-4 rad over a metre, about 1e-6 deg).
  Table2Scenario sc = table2Scenario();
  std::mt19937_64 rng(9);
  std::normal_distribution<double> normal;
  for (int l = 0; l < kLinkParameterCount; ++l)
    sc.truth.link[l] = l % 3 == 2 ? 0.01 * kDegToRad * normal(rng) : 0.1 * normal(rng);
  const auto recorded = record(sc.cell, sc.truth, centresOf(sc), threePlacementPlan());
  SolveOptions options;
  options.noise_mm = 0.01;
  const SolveReport r = solve(sc.cell, recorded, options);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.rms_miss_mm, 1e-7);
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(r.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 1e-5) << k;
}

TEST(SeveralPlacements, NameWhatThePosesCannotIdentifyAndWhy) {
  const Table2Scenario sc = table2Scenario();
  const auto recorded = record(sc.cell, sc.truth, centresOf(sc), threePlacementPlan());
  SolveOptions options;
  options.noise_mm = 0.01;
  const SolveReport r = solve(sc.cell, recorded, options);
  auto reason = [&](const std::string& name) {
    for (const auto& n : r.not_identifiable)
      if (n.name == name) return n.reason;
    return std::string("identified");
  };
  // d1 moves every line along the joint-1 axis: the centres follow.
  EXPECT_NE(reason("dd1_mm").find("combined with the placement-1 centre"), std::string::npos)
      << reason("dd1_mm");
  // The flange's own link moves the laser line in the flange frame: the laser absorbs it; along
  // and about the nominal beam (flange x) it does not move the line at all.
  EXPECT_NE(reason("dd6_mm").find("combined with the laser line"), std::string::npos)
      << reason("dd6_mm");
  EXPECT_EQ(reason("da6_mm"), "no effect on the measurements at these poses");
  EXPECT_EQ(reason("dalpha6_deg"), "no effect on the measurements at these poses");
  // Joints 2 and 3 are parallel: d2 and d3 shift along the same axis.
  EXPECT_NE(reason("dd3_mm").find("dd2"), std::string::npos) << reason("dd3_mm");
  EXPECT_EQ(reason("delta1_deg"), delta1Reason());
  const ParameterEstimate* dd1 = find(r, "dd1_mm");
  ASSERT_NE(dd1, nullptr);
  EXPECT_FALSE(dd1->identifiable);
  const ParameterEstimate* a2 = find(r, "da2_mm");
  ASSERT_NE(a2, nullptr);
  EXPECT_TRUE(a2->identifiable) << a2->reason;
}

TEST(BaseParameters, NameTheComplianceWhenThePosesCannotTellItFromAnOffset) {
  const std::vector<Pose> poses = atPlacement(testing::storedPlan("table2-8"), 1);
  const PlacementLayout layout(poses, table2Scenario().cell.robot, true);
  ASSERT_EQ(layout.compliance, kComplianceCount);
  std::mt19937_64 rng(4);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd jac(60, layout.unknownCount());
  for (int r = 0; r < jac.rows(); ++r)
    for (int c = 0; c < jac.cols(); ++c) jac(r, c) = normal(rng);
  // A pose set whose torque on joint 3 is the same at every pose: its compliance is its offset.
  const int c3 = PlacementLayout::firstCompliance() + 1;
  jac.col(c3) = 0.3 * jac.col(1);
  const BaseParameters base = analyseBaseParameters(jac, layout);
  EXPECT_TRUE(base.identified[PlacementLayout::firstCompliance()]);
  EXPECT_FALSE(base.identified[c3]);
  EXPECT_EQ(layout.name(c3), "compliance3_deg_per_knm");
  EXPECT_NE(base.reason[c3].find("combined with delta3"), std::string::npos) << base.reason[c3];
}

// A robot file with the true compliance: its sag on the recorded poses (servoOnto turns joints 2
// and 3 by it), identified back when asked, else counted in the offsets' sigmas as a tolerance.
TEST(SeveralPlacements, IdentifyTheComplianceOfJoints2And3OrCountItsSag) {
  Table2Scenario sc = table2Scenario();
  CellModel sagging = sc.cell;
  sagging.robot.compliance_deg_per_knm = {0.015, 0.02};  // about 0.007 and 0.003 deg at most
  const auto recorded = record(sagging, sc.truth, centresOf(sc), threePlacementPlan());
  SolveOptions options;
  options.noise_mm = 0.01;
  options.identify_compliance = true;
  const SolveReport r = solve(sc.cell, recorded, options);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.rms_miss_mm, 1e-7);
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(r.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 1e-6) << k;
  for (int c = 0; c < kComplianceCount; ++c) {
    const ParameterEstimate* p = find(r, complianceParamName(c));
    ASSERT_NE(p, nullptr);
    EXPECT_TRUE(p->identifiable) << p->reason;
    EXPECT_NEAR(p->value, sagging.robot.compliance_deg_per_knm[c], 1e-6);
  }

  // Not identified: the sag biases delta2 and delta3, and its tolerance widens their sigmas.
  options.identify_compliance = false;
  const SolveReport plain = solve(sc.cell, recorded, options);
  options.model.sag_deg = {0.01, 0.006};
  const SolveReport counted = solve(sc.cell, recorded, options);
  EXPECT_EQ(find(plain, "compliance2_deg_per_knm"), nullptr);
  EXPECT_EQ(counted.model_sag_deg[0], 0.01);
  EXPECT_EQ(counted.model_sag_deg[1], 0.006);
  for (int k = 0; k < 2; ++k) {
    const double error = std::abs(plain.parameters[k].value - sc.truth.delta_rad[k] * kRadToDeg);
    EXPECT_GT(error, 3 * plain.parameters[k].sigma) << k;  // the bias a tolerance must cover
    EXPECT_GT(counted.parameters[k].model_sigma, plain.parameters[k].model_sigma) << k;
    EXPECT_LT(error, 3 * counted.parameters[k].sigma) << k;
  }
}

// The sags of joints 2 and 3 both have gravity's sign: given their means, they are counted as
// drawn together (second moment sag_deg^2 on the diagonal, the means' product off it). With each
// mean at its RMS the two are one draw, and each offset's sag variance is the square of the sum
// or the difference of the two sags' separate sigmas; without means it is the sum of their
// variances. At one placement and at three.
TEST(SeveralPlacements, TheSagsOfJoints2And3AreCountedTogetherWhenTheirMeansAreGiven) {
  const Table2Scenario sc = table2Scenario();
  const std::vector<Pose>& planned = threePlacementPlan();
  const std::vector<Pose> first(planned.begin(), planned.begin() + 10);
  for (const std::vector<Pose>* plan : {&first, &planned}) {
    const auto recorded = record(sc.cell, sc.truth, centresOf(sc), *plan);
    const auto modelVariance = [&](SagTolerances sag, SagTolerances mean) {
      SolveOptions options;
      options.noise_mm = 0.02;
      options.model.sag_deg = sag;
      options.model.sag_mean_deg = mean;
      const SolveReport r = solve(sc.cell, recorded, options);
      EXPECT_TRUE(r.converged) << r.message;
      EXPECT_EQ(r.model_sag_mean_deg, mean);
      std::array<double, 2> v{};
      for (int k = 0; k < 2; ++k) v[k] = std::pow(r.parameters[k].model_sigma, 2);
      return v;
    };
    const auto joint2 = modelVariance({0.007, 0}, {});
    const auto joint3 = modelVariance({0, 0.0042}, {});
    const auto apart = modelVariance({0.007, 0.0042}, {});
    const auto together = modelVariance({0.007, 0.0042}, {0.007, 0.0042});
    const auto shipped = modelVariance({0.007, 0.0042}, {0.0065, 0.004});
    for (int k = 0; k < 2; ++k) {
      const std::string what =
          std::to_string(plan->size()) + " poses, delta" + std::to_string(k + 2);
      ASSERT_GT(joint2[k], 0) << what;
      ASSERT_GT(joint3[k], 0) << what;
      EXPECT_NEAR(apart[k], joint2[k] + joint3[k], 1e-6 * apart[k]) << what;
      const double sum = std::pow(std::sqrt(joint2[k]) + std::sqrt(joint3[k]), 2);
      const double difference = std::pow(std::sqrt(joint2[k]) - std::sqrt(joint3[k]), 2);
      EXPECT_LT(std::min(std::abs(together[k] - sum), std::abs(together[k] - difference)),
                1e-6 * apart[k])
          << what;
      // The shipped means lie between: 0.88 of the way from apart to together.
      const double share = (shipped[k] - apart[k]) / (together[k] - apart[k]);
      EXPECT_NEAR(share, 0.0065 * 0.004 / (0.007 * 0.0042), 1e-6) << what;
    }
  }
}

// One pose recorded with a joint 0.05 deg off (read before the arm settled): named, left out,
// and the result rests on the others.
TEST(SeveralPlacements, NameAndLeaveOutAPoseThatDoesNotFit) {
  const Table2Scenario sc = table2Scenario();
  auto recorded = record(sc.cell, sc.truth, centresOf(sc), threePlacementPlan());
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal;
  for (Pose& p : recorded)  // a little noise, so that the misfit has a scale
    for (int j = 1; j < 5; ++j) p.q_deg[j] += 2e-4 * normal(rng);
  constexpr int kBad = 13;  // placement 2
  recorded[kBad].q_deg[2] += 0.05;
  SolveOptions options;
  options.noise_mm = 0.01;
  const SolveReport r = solve(sc.cell, recorded, options);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(r.verdict.usable) << ::testing::PrintToString(r.verdict.reasons);
  ASSERT_EQ(r.suspect_poses.size(), 1u);
  EXPECT_EQ(r.suspect_poses[0].pose, kBad + 1);
  EXPECT_GT(r.suspect_poses[0].chi2_without, 0);
  EXPECT_NE(r.suspect_poses[0].reason.find("does not fit the other poses"), std::string::npos);
  EXPECT_TRUE(r.poses[kBad].outlier);
  EXPECT_FALSE(r.poses[kBad].used);
  EXPECT_EQ(r.poses_used, static_cast<int>(recorded.size()) - 1);
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(r.parameters[k].value, sc.truth.delta_rad[k] * kRadToDeg, 3 * r.parameters[k].sigma)
        << k;
}

// The same error at a placement of only 3 poses: leaving it out would leave that centre
// without its check, so the result is refused and the pose is named to be measured again.
TEST(SeveralPlacements, RefuseAPoseThatDoesNotFitWhenItsPlacementCannotSpareIt) {
  const Table2Scenario sc = table2Scenario();
  std::vector<Pose> planned;
  int at_third = 0;
  for (const Pose& p : threePlacementPlan())
    if (p.placement != 3 || at_third++ < 3) planned.push_back(p);
  auto recorded = record(sc.cell, sc.truth, centresOf(sc), planned);
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal;
  for (Pose& p : recorded)
    for (int j = 1; j < 5; ++j) p.q_deg[j] += 2e-4 * normal(rng);
  const int bad = static_cast<int>(recorded.size()) - 2;  // placement 3
  ASSERT_EQ(recorded[bad].placement, 3);
  recorded[bad].q_deg[1] += 0.05;
  SolveOptions options;
  options.noise_mm = 0.01;
  const SolveReport r = solve(sc.cell, recorded, options);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_FALSE(r.verdict.usable);
  const std::string reasons = ::testing::PrintToString(r.verdict.reasons);
  EXPECT_NE(reasons.find("placement 3 would keep only 2 poses"), std::string::npos) << reasons;
  EXPECT_EQ(r.remeasure, std::vector<int>{bad + 1});
}

TEST(SeveralPlacements, OnePlacementNumberedOtherThanOneSolvesAsBefore) {
  const Table2Scenario sc = table2Scenario();
  std::mt19937_64 rng(7);
  const auto recorded =
      simulateRecording(sc.cell, sc.truth, testing::storedPlan("table2-8"), 0.05, rng);
  SolveOptions options;
  options.noise_mm = 0.0289;
  const SolveReport one = solve(sc.cell, recorded, options);
  const SolveReport two = solve(sc.cell, atPlacement(recorded, 2), options);
  EXPECT_TRUE(two.placements.empty());
  ASSERT_EQ(two.parameters.size(), static_cast<std::size_t>(kIdentifiedCount));
  for (int k = 0; k < kIdentifiedCount; ++k) {
    EXPECT_EQ(one.parameters[k].value, two.parameters[k].value) << k;
    EXPECT_EQ(one.parameters[k].sigma, two.parameters[k].sigma) << k;
  }
  EXPECT_EQ(one.rank, kUnknownCount);
}

TEST(SeveralPlacements, RefuseWhatTheyDoNotOfferAndTooFewPosesAtAPlacement) {
  const Table2Scenario sc = table2Scenario();
  std::vector<Pose> poses = threePlacementPlan();
  SolveOptions pairwise;
  pairwise.cost = CostKind::kPairwise;
  EXPECT_THROW(
      {
        try {
          solve(sc.cell, poses, pairwise);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("only the maximum-likelihood cost"),
                    std::string::npos);
          throw;
        }
      },
      InputError);
  std::vector<Pose> thin(poses.begin(), poses.begin() + 12);  // placement 2 has 2 poses
  ASSERT_EQ(thin.back().placement, 2);
  EXPECT_THROW(
      {
        try {
          solve(sc.cell, thin, {});
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("placement 2 has 2 poses"), std::string::npos)
              << e.what();
          throw;
        }
      },
      InputError);
}

TEST(SeveralPlacements, ThePlanPredictsTheLinkErrorsTheyIdentify) {
  const Table2Scenario sc = table2Scenario();
  const std::vector<Pose>& planned = threePlacementPlan();
  const Prediction three = predictUncertainty(sc.cell, planned, {}, 0.02);
  EXPECT_EQ(three.placements, 3);
  ASSERT_EQ(three.link_sigma.size(), static_cast<std::size_t>(kLinkParameterCount));
  int identified = 0;
  for (int l = 0; l < kLinkParameterCount; ++l) {
    if (!three.link_identifiable[l]) {
      EXPECT_TRUE(std::isnan(three.link_sigma[l]));
      EXPECT_FALSE(three.link_reason[l].empty());
      continue;
    }
    ++identified;
    EXPECT_GT(three.link_sigma[l], 0) << linkParamName(l);
  }
  EXPECT_GE(identified, 10);
  for (int k = 0; k < kOffsetCount; ++k) EXPECT_TRUE(three.identifiable[k]) << three.reason[k];
  EXPECT_TRUE(std::isfinite(three.rms_offset_sigma_deg));
  // One placement's poses keep the one-placement prediction.
  std::vector<Pose> first(planned.begin(), planned.begin() + 10);
  const Prediction one = predictUncertainty(sc.cell, first, sc.truth, 0.02);
  EXPECT_EQ(one.placements, 1);
  EXPECT_TRUE(one.link_sigma.empty());
}

// The plan's prediction counts what the solve will count beside the noise (the tolerances of the
// link errors the poses do not identify, the sag), with several placements and with one: the
// solve's sigmas on noiseless poses are what the plan predicted.
TEST(SeveralPlacements, ThePlanPredictsWhatTheSolveCountsBesideTheNoise) {
  const Table2Scenario sc = table2Scenario();
  const std::vector<Pose>& planned = threePlacementPlan();
  SolveOptions options;
  options.noise_mm = 0.02;
  options.model.length_mm = 0.1;
  options.model.angle_deg = 0.01;
  options.model.sag_deg = {0.007, 0.0042};
  options.model.sag_mean_deg = {0.0065, 0.004};
  options.required_accuracy_deg = 0.5;
  const ModelTolerances tolerances = options.model;
  const std::vector<Pose> first(planned.begin(), planned.begin() + 10);
  CalibrationParameters nominal;  // as zerocald predicts: the nominal cell at the first centre
  nominal.target_mm = sc.truth.target_mm;
  for (const std::vector<Pose>* plan : {&planned, &first}) {
    const SolveReport r = solve(sc.cell, record(sc.cell, sc.truth, centresOf(sc), *plan), options);
    ASSERT_TRUE(r.converged) << r.message;
    const Prediction counted = predictUncertainty(sc.cell, *plan, nominal, 0.02, tolerances);
    const Prediction noise_only = predictUncertainty(sc.cell, *plan, nominal, 0.02);
    for (int k = 0; k < kOffsetCount; ++k) {
      EXPECT_GE(counted.sigma[k], noise_only.sigma[k]) << plan->size() << " poses, " << k;
      EXPECT_NEAR(counted.sigma[k] / r.parameters[k].sigma, 1.0, 0.15)
          << plan->size() << " poses, delta" << k + 2;
    }
    // delta2 is what the tolerances widen most (the sag of joint 2; the links with one placement).
    EXPECT_GT(counted.sigma[0], 1.2 * noise_only.sigma[0]) << plan->size() << " poses";
  }
}

// A result saved as a calibrated robot file (what `zerocal-lab solve --save-model` writes) reads
// back with the identified link errors in its rows: solved again with it, the same poses leave no
// link error to find and the same offsets.
TEST(SeveralPlacements, ACalibratedModelReadsBackAndLeavesNoLinkErrorToFind) {
  const Table2Scenario sc = table2Scenario();
  CalibrationParameters truth = sc.truth;
  truth.link[3 * 1 + 0] = 0.3;               // a2 0.3 mm long
  truth.link[3 * 2 + 2] = 0.02 * kDegToRad;  // alpha3 twisted 0.02 deg
  truth.link[3 * 3 + 1] = -0.2;              // d4 0.2 mm short
  const auto recorded = record(sc.cell, truth, centresOf(sc), threePlacementPlan());
  SolveOptions options;
  options.noise_mm = 0.01;
  const SolveReport first = solve(sc.cell, recorded, options);
  ASSERT_TRUE(first.verdict.usable) << ::testing::PrintToString(first.verdict.reasons);
  const Robot saved = calibratedRobot(sc.cell.robot, first.estimate);
  const Robot back = parseRobot(robotYaml(saved, "calibrated by a test"), "test");
  for (int j = 0; j < kJointCount; ++j) {
    EXPECT_NEAR(back.dh[j].a_mm, saved.dh[j].a_mm, 1e-9) << j;
    EXPECT_NEAR(back.dh[j].d_mm, saved.dh[j].d_mm, 1e-9) << j;
    EXPECT_NEAR(back.dh[j].alpha_rad, saved.dh[j].alpha_rad, 1e-12) << j;
  }
  EXPECT_NEAR(back.dh[1].a_mm - sc.cell.robot.dh[1].a_mm, first.estimate.link[3], 1e-9);
  CellModel calibrated = sc.cell;
  calibrated.robot = back;
  const SolveReport again = solve(calibrated, recorded, options);
  ASSERT_TRUE(again.converged) << again.message;
  for (const ParameterEstimate& p : again.parameters)
    if (p.identifiable && p.name.rfind("d", 0) == 0 && p.name.rfind("delta", 0) != 0) {
      EXPECT_NEAR(p.value, 0.0, 1e-4) << p.name;
    }
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(again.parameters[k].value, first.parameters[k].value, 1e-5) << k;
}

// Solved with the link tolerances counted, several placements leave a calibrated model whose file
// carries the covariance of its links' remaining errors; a one-placement solve with that model
// counts that covariance instead of the nominal tolerances, and blurs the offsets less.
TEST(SeveralPlacements, ACalibratedModelCarriesItsLinkCovarianceIntoTheNextSolve) {
  const Table2Scenario sc = table2Scenario();
  CalibrationParameters truth = sc.truth;
  truth.link[3 * 1 + 0] = 0.1;
  truth.link[3 * 2 + 2] = 0.01 * kDegToRad;
  const auto recorded = record(sc.cell, truth, centresOf(sc), threePlacementPlan());
  SolveOptions options;
  options.noise_mm = 0.01;
  options.model.length_mm = 0.1;
  options.model.angle_deg = 0.01;
  const SolveReport first = solve(sc.cell, recorded, options);
  ASSERT_TRUE(first.converged) << first.message;
  ASSERT_EQ(first.link_covariance.rows(), kLinkParameterCount);
  const Robot saved = calibratedRobot(sc.cell.robot, first);
  ASSERT_TRUE(saved.tolerance.calibrated());
  const Robot back = parseRobot(robotYaml(saved, "calibrated by a test"), "test");
  ASSERT_TRUE(back.tolerance.calibrated());
  EXPECT_LT((back.tolerance.link_covariance - first.link_covariance).cwiseAbs().maxCoeff(),
            1e-12 * first.link_covariance.cwiseAbs().maxCoeff());
  // What the placements pinned down is known better than the nominal tolerance says.
  const Eigen::VectorXd sigmas = back.tolerance.linkSigmas();
  EXPECT_LT(sigmas.minCoeff(), 0.5 * 0.1);

  std::vector<Pose> one;
  for (const Pose& p : recorded)
    if (p.placement == 1) one.push_back(p);
  SolveOptions nominal = options;
  const SolveReport before = solve(sc.cell, one, nominal);
  CellModel calibrated = sc.cell;
  calibrated.robot = back;
  SolveOptions with_model = options;
  with_model.model = back.tolerance;
  const SolveReport after = solve(calibrated, one, with_model);
  ASSERT_TRUE(before.converged && after.converged);
  EXPECT_FALSE(before.model_calibrated);
  EXPECT_TRUE(after.model_calibrated);
  double worst_before = 0, worst_after = 0;
  for (int k = 0; k < kOffsetCount; ++k) {
    if (!before.parameters[k].identifiable || !after.parameters[k].identifiable) continue;
    worst_before = std::max(worst_before, before.parameters[k].model_sigma);
    worst_after = std::max(worst_after, after.parameters[k].model_sigma);
  }
  EXPECT_GT(worst_before, 0);
  EXPECT_LT(worst_after, 0.7 * worst_before) << worst_after << " vs " << worst_before;
}

}  // namespace
}  // namespace zerocal
