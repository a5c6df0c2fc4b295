// The results codec on its own, as the technician's client links it (nothing but zerocal::results):
// a result.json and a session.json built by hand come back member for member, and a result from
// before verdicts reads as one whose verdict was not recorded. The files the engine and the daemon
// write are round-tripped in tests/store (session_files_test.cpp).
#include <gtest/gtest.h>

#include "zerocal/error.h"
#include "zerocal/results/result_file.h"
#include "zerocal/results/session_file.h"

namespace zerocal {
namespace {

using nlohmann::json;

ResultFile aResult() {
  ResultFile r;
  r.report.verdict = {true, {}};
  r.report.converged = true;
  r.report.message = "converged";
  r.report.pose_count = r.report.poses_used = 8;
  for (int k = 0; k < kIdentifiedCount; ++k)
    r.report.parameters.push_back(
        {unknownName(k), true, "", 0.1 * k, 0.002, 0, 0.1 * k - 0.004, 0.1 * k + 0.004});
  r.report.parameters[3].identifiable = false;
  r.report.parameters[3].reason = "delta5 trades against the laser";
  r.report.not_identifiable = {{"delta1_deg", "about the base axis"}};
  r.report.estimate.target_mm = {900, -50, 400};
  r.report.poses.resize(8);
  r.session = "20261122T073447Z";
  r.cell_time_s = 55.9;
  r.cell = ResultFile::Cell{{"1600-123456", "6.15", "IRB 1600-10/1.45"}, "psd-map.yaml"};
  r.truth = ResultFile::Truth{{-0.7, 0.1, -0.9, -0.3}, ""};
  PoseTimes measured, skipped;
  measured.pose = 1;
  measured.servo.moves = 3;
  measured.servo.move_s = 1.5;
  measured.move_overhead_s = 0.3;
  skipped.pose = 2;
  skipped.skipped = "the spot was never found";
  r.pose_breakdown = std::vector<PoseTimes>{measured, skipped};
  return r;
}

TEST(ResultsCodec, AResultComesBackMemberForMember) {
  const json j = toJson(aResult());
  const ResultFile back = resultFileFromJson(j);
  EXPECT_EQ(toJson(back), j);
  EXPECT_EQ(back.session, "20261122T073447Z");
  ASSERT_TRUE(back.cell);
  EXPECT_EQ(back.cell->controller.serial, "1600-123456");
  EXPECT_FALSE(back.report.parameters[3].identifiable);
  EXPECT_EQ(back.pose_breakdown->at(1).skipped, "the spot was never found");
  EXPECT_TRUE(back.verdict_recorded);
}

// The sag tolerances counted come back per joint; a result written when one tolerance stood for
// both joints reads as that for each.
TEST(ResultsCodec, TheSagTolerancesCountedComeBackPerJoint) {
  ResultFile r = aResult();
  r.report.model_sag_deg = {0.007, 0.0042};
  json j = toJson(r);
  EXPECT_EQ(j["model_tolerance"]["sag_deg"], json::array({0.007, 0.0042}));
  EXPECT_EQ(resultFileFromJson(j).report.model_sag_deg, r.report.model_sag_deg);
  j["model_tolerance"]["sag_deg"] = 0.007;
  const auto old = resultFileFromJson(j).report.model_sag_deg;
  EXPECT_EQ(old[0], 0.007);
  EXPECT_EQ(old[1], 0.007);
  EXPECT_FALSE(toJson(aResult())["model_tolerance"].contains("sag_deg"));  // none counted
  EXPECT_FALSE(j["model_tolerance"].contains("sag_mean_deg"));             // counted as independent
  r.report.model_sag_mean_deg = {0.0065, 0.004};
  j = toJson(r);
  EXPECT_EQ(j["model_tolerance"]["sag_mean_deg"], json::array({0.0065, 0.004}));
  EXPECT_EQ(resultFileFromJson(j).report.model_sag_mean_deg, r.report.model_sag_mean_deg);
}

TEST(ResultsCodec, AResultFromBeforeVerdictsSaysSo) {
  json j = toJson(aResult());
  j.erase("verdict");
  EXPECT_FALSE(resultFileFromJson(j).verdict_recorded);
  j.erase("converged");
  EXPECT_THROW(resultFileFromJson(j), InputError);
}

TEST(ResultsCodec, ASessionFileComesBack) {
  SessionFile s;
  s.id = "20261122T073447Z";
  s.plan.description = "optimal";
  Pose pose;
  pose.q_deg = {10, -5, 20, 45, -30, 0};
  s.plan.poses = {pose, pose};
  s.plan.prediction.sigma.assign(kIdentifiedCount, 0.002);
  s.plan.prediction.identifiable.assign(kIdentifiedCount, true);
  s.plan.prediction.reason.assign(kIdentifiedCount, "");
  s.target_mm = {900, -50, 400};
  s.noise_mm = 0.02;
  s.config = {{"session", {{"poses", 2}}}};
  const json j = toJson(s);
  EXPECT_EQ(toJson(sessionFileFromJson(j)), j);
}

// A restore's and a check's result: the kind, the reference, the change said as such, the
// check's judgement; an unknown kind or outcome is refused, naming it.
TEST(ResultsCodec, AResultAgainstAReferenceSaysSoAndComesBack) {
  ResultFile r = aResult();
  r.kind = SessionKind::kCheck;
  r.reference = "20261121T060000Z";
  r.check = CheckJudgement{CheckJudgement::Outcome::kChanged, {3}, 0.01, "joint 3 moved"};
  const json j = toJson(r);
  EXPECT_EQ(j["kind"], "check");
  EXPECT_EQ(j["reference"], "20261121T060000Z");
  EXPECT_DOUBLE_EQ(j["change"]["delta3_deg"]["value"].get<double>(), 0.1);
  EXPECT_DOUBLE_EQ(j["change"]["delta3_deg"]["sigma"].get<double>(), 0.002);
  EXPECT_EQ(j["check"]["outcome"], "changed");
  const ResultFile back = resultFileFromJson(j);
  EXPECT_EQ(toJson(back), j);
  EXPECT_EQ(back.kind, SessionKind::kCheck);
  ASSERT_TRUE(back.check);
  EXPECT_EQ(back.check->joints, std::vector<int>{3});
  // A calibration's says its kind and nothing of a reference.
  const json calibration = toJson(aResult());
  EXPECT_EQ(calibration["kind"], "calibration");
  EXPECT_FALSE(calibration.contains("change"));
  json bad = j;
  bad["kind"] = "recalibration";
  EXPECT_THROW(resultFileFromJson(bad), InputError);
  bad = j;
  bad["check"]["outcome"] = "fine";
  EXPECT_THROW(resultFileFromJson(bad), InputError);
  bad = j;
  bad["check"]["joints"] = {7};
  EXPECT_THROW(resultFileFromJson(bad), InputError);
}

TEST(ResultsCodec, ASessionAgainstAReferenceNamesItAndAPosePerPlanPose) {
  SessionFile s;
  s.id = "20261122T073447Z";
  s.kind = SessionKind::kRestore;
  s.reference = "20261121T060000Z";
  Pose pose;
  pose.q_deg = {10, -5, 20, 45, -30, 0};
  s.plan.poses = {pose, pose};
  s.reference_poses = {4, 9};
  s.plan.prediction.sigma.assign(kIdentifiedCount, 0.002);
  s.plan.prediction.identifiable.assign(kIdentifiedCount, true);
  s.plan.prediction.reason.assign(kIdentifiedCount, "");
  s.target_mm = {900, -50, 400};
  s.noise_mm = 0.02;
  const json j = toJson(s);
  const SessionFile back = sessionFileFromJson(j);
  EXPECT_EQ(toJson(back), j);
  EXPECT_EQ(back.kind, SessionKind::kRestore);
  EXPECT_EQ(back.reference_poses, (std::vector<int>{4, 9}));
  json bad = j;
  bad["reference_poses"] = {4};
  EXPECT_THROW(sessionFileFromJson(bad), InputError);  // one per plan pose
  bad = j;
  bad.erase("reference");
  bad.erase("reference_poses");
  EXPECT_THROW(sessionFileFromJson(bad), InputError);  // a restore names its reference
  bad = j;
  bad["kind"] = "rehearsal";
  EXPECT_THROW(sessionFileFromJson(bad), InputError);
}

}  // namespace
}  // namespace zerocal

namespace zerocal {
namespace {

// A plan nobody predicted (empty prediction vectors) writes and reads back as "not predicted",
// instead of reading past the vectors' end.
TEST(ResultsCodec, APlanWithoutAPredictionWritesAndReadsBack) {
  Plan plan;
  plan.poses.push_back(Pose{Joints{1, 2, 3, 4, 5, 6}, {}, 0});
  plan.prediction.placements = 2;  // the link part is written too, and is empty as well
  const nlohmann::json j = toJson(plan);
  EXPECT_TRUE(j["predicted"].empty()) << j.dump();
  const Plan back = planFromJson(j, "plan");
  ASSERT_EQ(back.poses.size(), 1u);
  ASSERT_EQ(back.prediction.identifiable.size(), static_cast<std::size_t>(kIdentifiedCount));
  EXPECT_FALSE(back.prediction.identifiable[0]);
  EXPECT_EQ(back.prediction.reason[0], "not predicted");
  EXPECT_FALSE(j.contains("required_accuracy_deg"));  // not judged
  // The accuracy a daemon judged the plan by travels with it, and a wrong one is refused.
  plan.prediction.required_accuracy_deg = 0.01;
  nlohmann::json judged = toJson(plan);
  EXPECT_EQ(planFromJson(judged, "plan").prediction.required_accuracy_deg, 0.01);
  judged["required_accuracy_deg"] = -1;
  EXPECT_THROW(planFromJson(judged, "plan"), InputError);
  // So does its predicted cell time, when it has one.
  EXPECT_FALSE(j.contains("predicted_cell_time"));
  plan.prediction.cell_time_s = 47.25;
  plan.prediction.cell_time_per_pose_s = 5.25;
  plan.prediction.cell_time_sessions = 4;
  nlohmann::json timed = toJson(plan);
  const Prediction t = planFromJson(timed, "plan").prediction;
  EXPECT_EQ(t.cell_time_s, 47.25);
  EXPECT_EQ(t.cell_time_per_pose_s, 5.25);
  EXPECT_EQ(t.cell_time_sessions, 4);
  timed["predicted_cell_time"]["from_sessions"] = 0;
  EXPECT_THROW(planFromJson(timed, "plan"), InputError);
}

}  // namespace
}  // namespace zerocal
