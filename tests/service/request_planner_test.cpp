// The planner of requests without a session, a thread or a cell that moves: the one rule for
// poses given up, as the resume's --skip-pose check and the fault's advice apply it.
#include "zerocal/service/request_planner.h"

#include <gtest/gtest.h>

#include "stored_plan.h"
#include "zerocal/sim/sim_backend.h"

namespace zerocal::service {
namespace {

// The sessions' noise on the simulated cell, as the manager's tests have it.
constexpr double kNoiseMm = 0.020;

struct PlannerFixture {
  explicit PlannerFixture(ModelTolerances tolerances, const std::string& plan_name)
      : backend(sim::seededCellOptions(5, WorldKind::kIdeal)), knowledge(backend.knowledge()) {
    PlannerSettings settings;
    settings.noise_mm = kNoiseMm;
    settings.tolerances = tolerances;
    planner.emplace(knowledge, backend, settings);
    plan.poses = testing::storedPlan(plan_name);
    plan.target = knowledge.taught_centre_mm;
    plan.noise_mm = kNoiseMm;
  }
  sim::SimBackend backend;
  CellKnowledge knowledge;
  std::optional<RequestPlanner> planner;
  RunPlan plan;
};

// `count` measured poses, as a journal read back has them.
std::vector<PoseRecord> measured(int count) {
  std::vector<PoseRecord> records(count);
  for (int i = 0; i < count; ++i) records[i].index = i;
  return records;
}

bool identifiesEveryOffset(const Prediction& p) {
  for (int k = 0; k < kOffsetCount; ++k)
    if (!p.identifiable[k]) return false;
  return true;
}

// Link and sag tolerances this large (4 mm, 0.4 deg) leave the two-placement plan of seed 5
// identifying every offset, but not without its pose 4: a skip the solve, counting them, would
// refuse, though a prediction without them would let it through.
const ModelTolerances kLargeTolerances{3.8, 0.38, {0.38, 0.38}, {}};
constexpr const char* kTwoPlacements = "ideal-5-2-placements";

// A plan predicted short of the required accuracy moves nothing unless asked for: the robot's
// link tolerances at one placement leave delta2..delta5 beyond 0.01 deg.
TEST(RequestPlanner, APlanPredictedShortOfTheRequiredAccuracyStartsOnlyWhenAskedFor) {
  StartRequest request;
  request.plan = PlanKind::kFile;
  request.plan_file = testing::storedPlanPath("ideal-5");
  const PlannerFixture exact({}, "ideal-5");
  EXPECT_NO_THROW(exact.planner->plan(request));  // the model taken as exact: 0.003 deg
  const PlannerFixture tolerant({0.1, 0.01, {}, {}}, "ideal-5");
  const Plan preview = tolerant.planner->preview(request);  // a preview is never refused
  ASSERT_GT(preview.prediction.sigma[0], 0.01);
  try {
    tolerant.planner->plan(request);
    FAIL() << "a plan short of 0.01 deg was let go";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "not_accurate") << e.what();
    const std::string what = e.what();
    for (const char* part : {"delta2 only to", "against the required 0.0100 deg", "nothing moved",
                             "--placements 3", "--even-if-not-usable"})
      EXPECT_NE(what.find(part), std::string::npos) << part << " in: " << what;
  }
  request.even_if_not_usable = true;
  const PlannedSession asked = tolerant.planner->plan(request);
  EXPECT_EQ(asked.run.poses.size(), preview.poses.size());
}

// Every comparison with a reference counts how closely the PSD's base puts it back.
TEST(RequestPlanner, EveryChangeCountsThePsdsBase) {
  sim::SimBackend backend(sim::seededCellOptions(5, WorldKind::kIdeal));
  PlannerSettings settings;
  settings.noise_mm = kNoiseMm;
  settings.psd_base_repeatability_mm = 0.02;
  const RequestPlanner planner(backend.knowledge(), backend, settings);
  for (const SessionKind kind :
       {SessionKind::kCheck, SessionKind::kRestore, SessionKind::kVerification})
    EXPECT_EQ(planner.changeOptions(kind).psd_base_repeatability_mm, 0.02);
}

TEST(RequestPlanner, ASkipTheSolveWouldRefuseIsRefusedAtResumeAndNotOfferedAfterAFault) {
  PlannerFixture f(kLargeTolerances, kTwoPlacements);
  CalibrationParameters nominal;
  nominal.target_mm = f.plan.target;
  std::vector<Pose> without_4 = f.plan.poses;
  without_4.erase(without_4.begin() + 3);
  // The premise: the tolerances alone make the difference.
  ASSERT_TRUE(identifiesEveryOffset(
      predictUncertainty(f.knowledge.cell, f.plan.poses, nominal, kNoiseMm, kLargeTolerances)));
  ASSERT_TRUE(
      identifiesEveryOffset(predictUncertainty(f.knowledge.cell, without_4, nominal, kNoiseMm)));
  ASSERT_FALSE(identifiesEveryOffset(
      predictUncertainty(f.knowledge.cell, without_4, nominal, kNoiseMm, kLargeTolerances)));

  const std::string id = "20261203T120000Z";
  // Three poses recorded, the fourth faulted.
  try {
    f.planner->checkResume(id, f.plan, measured(3), 3, 4);
    FAIL() << "pose 4 was let go";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "not_identifiable") << e.what();
    EXPECT_NE(std::string(e.what()).find("without pose 4"), std::string::npos) << e.what();
  }
  const SkipAdvice advice = f.planner->adviseSkip(id, f.plan, measured(3), 3);
  EXPECT_EQ(advice.skippable_pose, 0);
  EXPECT_NE(advice.advice.find("plan a new session"), std::string::npos) << advice.advice;
  // Resumed without a skip it goes on.
  EXPECT_EQ(f.planner->checkResume(id, f.plan, measured(3), 3, 0), -1);
}

TEST(RequestPlanner, ASkipThePlanCanDoWithoutIsOfferedAndTakenAlike) {
  PlannerFixture f(kLargeTolerances, kTwoPlacements);
  const std::string id = "20261203T120000Z";
  const SkipAdvice advice = f.planner->adviseSkip(id, f.plan, measured(0), 0);
  EXPECT_EQ(advice.skippable_pose, 1);
  EXPECT_NE(advice.advice.find("`zerocal resume " + id + " --skip-pose 1`"), std::string::npos)
      << advice.advice;
  EXPECT_EQ(f.planner->checkResume(id, f.plan, measured(0), 0, 1), 0);
  // Only the next pose to measure can be skipped.
  try {
    f.planner->checkResume(id, f.plan, measured(3), 3, 5);
    FAIL() << "pose 5 was skipped before pose 4";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "bad_request") << e.what();
  }
}

// The resume's check and the fault's advice are one rule: for every pose of the plan, the skip
// is offered exactly when it is taken, and exactly when the plan identifies every offset without
// it and the poses skipped before.
TEST(RequestPlanner, TheResumeAndTheFaultAdviceAgreeOnEveryPose) {
  PlannerFixture f(kLargeTolerances, kTwoPlacements);
  const std::string id = "20261203T120000Z";
  std::vector<PoseRecord> records = measured(1);
  records[0].skipped = "spot not found";  // pose 1 given up already
  int offered = 0, refused = 0;
  for (int next = 1; next < static_cast<int>(f.plan.poses.size()); ++next) {
    std::vector<PoseRecord> before = records;
    for (int i = 1; i < next; ++i) before.push_back(measured(i + 1).back());
    std::vector<bool> skipped(f.plan.poses.size(), false);
    skipped[0] = skipped[next] = true;
    const bool identifies = f.planner->identifiesWithout(f.plan, skipped);
    const SkipAdvice advice = f.planner->adviseSkip(id, f.plan, before, next);
    bool taken = true;
    try {
      EXPECT_EQ(f.planner->checkResume(id, f.plan, before, next, next + 1), next);
    } catch (const Refused& e) {
      EXPECT_EQ(e.code(), "not_identifiable") << e.what();
      taken = false;
    }
    EXPECT_EQ(advice.skippable_pose != 0, identifies) << "pose " << next + 1;
    EXPECT_EQ(taken, identifies) << "pose " << next + 1;
    (identifies ? offered : refused) += 1;
  }
  // The tolerances leave both kinds in this plan.
  EXPECT_GT(offered, 0);
  EXPECT_GT(refused, 0);
}

}  // namespace
}  // namespace zerocal::service
