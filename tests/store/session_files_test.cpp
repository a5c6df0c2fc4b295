// The store's codecs are the only code that reads and writes session.json and result.json: every
// member written must come back, so a file read and written again is the same file.
#include "zerocal/store/session_files.h"

#include <gtest/gtest.h>

#include <cmath>

#include "session_fixture.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

using nlohmann::json;

void expectRoundTrip(const SessionFolder& files) {
  const json session = toJson(files.session);
  EXPECT_EQ(toJson(sessionFileFromJson(session)), session);
  const json result = toJson(files.result);
  EXPECT_EQ(toJson(resultFileFromJson(result)), result);
}

TEST(SessionFiles, EveryMemberOfAFinishedSessionComesBack) {
  expectRoundTrip(test::sessionFiles());
  test::FixtureOptions held_out;
  held_out.held_out = {3, 7};
  expectRoundTrip(test::sessionFiles(held_out));
  test::FixtureOptions resumed;
  resumed.skipped = {2};
  resumed.remeasured = {4};
  resumed.identity = false;
  expectRoundTrip(test::sessionFiles(resumed));
}

// What a session is for: a verification names the session whose apply it verifies; a file
// written before kinds is a calibration; an unknown kind is refused, not taken for one.
TEST(SessionFiles, ASessionsKindComesBackAndAnUnknownOneIsRefused) {
  SessionFile s = test::sessionFiles().session;
  EXPECT_EQ(toJson(s)["kind"], "calibration");
  s.kind = SessionKind::kVerification;
  s.verifies = "20261122T073447Z";
  const json j = toJson(s);
  EXPECT_EQ(j["kind"], "verification");
  const SessionFile back = sessionFileFromJson(j);
  EXPECT_EQ(back.kind, SessionKind::kVerification);
  EXPECT_EQ(back.verifies, "20261122T073447Z");
  json old = j;
  old.erase("kind");
  old.erase("verifies");
  EXPECT_EQ(sessionFileFromJson(old).kind, SessionKind::kCalibration);
  json unknown = j;
  unknown["kind"] = "calibrashun";
  EXPECT_THROW(sessionFileFromJson(unknown), InputError);
}

// A session at several PSD placements: each pose's placement, the placements' planned centres,
// the plan's link-error prediction, and the result's placement centres and link errors.
TEST(SessionFiles, ASessionAtSeveralPlacementsComesBack) {
  SessionFolder files = test::sessionFiles();
  SessionFile& s = files.session;
  for (std::size_t i = 0; i < s.plan.poses.size(); ++i)
    s.plan.poses[i].placement = 2 * i < s.plan.poses.size() ? 1 : 2;
  s.plan.prediction.placements = 2;
  s.plan.prediction.link_sigma.assign(kLinkParameterCount, 0.05);
  s.plan.prediction.link_identifiable.assign(kLinkParameterCount, true);
  s.plan.prediction.link_reason.assign(kLinkParameterCount, "");
  s.plan.prediction.link_sigma[1] = std::nan("");
  s.plan.prediction.link_identifiable[1] = false;
  s.plan.prediction.link_reason[1] = "combined with the placement-1 centre";
  s.placement_centres_mm = {s.target_mm, Eigen::Vector3d(610, 654.5, 583.75)};
  SolveReport& r = files.result.report;
  r.placements = {{1, 4, Eigen::Vector3d(900, -50, 400), Eigen::Vector3d(0.1, 0.1, 0.2)},
                  {2, 4, Eigen::Vector3d(610, 654.5, 583.75), Eigen::Vector3d(0.1, 0.2, 0.2)}};
  ParameterEstimate link;
  link.name = linkParamName(2);  // dalpha1_deg
  link.value = 0.004;
  link.sigma = 0.001;
  r.parameters.push_back(link);
  expectRoundTrip(files);

  const SessionFile back = sessionFileFromJson(toJson(s));
  ASSERT_EQ(back.placement_centres_mm.size(), 2u);
  EXPECT_EQ(back.placement_centres_mm[1], Eigen::Vector3d(610, 654.5, 583.75));
  EXPECT_EQ(back.plan.poses.back().placement, 2);
  EXPECT_EQ(back.plan.prediction.placements, 2);
  EXPECT_FALSE(back.plan.prediction.link_identifiable[1]);
  const SolveReport report = resultFileFromJson(toJson(files.result)).report;
  ASSERT_EQ(report.placements.size(), 2u);
  EXPECT_EQ(report.placements[1].target_mm, Eigen::Vector3d(610, 654.5, 583.75));
  EXPECT_DOUBLE_EQ(report.estimate.link[2], 0.004 * kDegToRad);
}

TEST(SessionFiles, TheDaemonsMembersComeBack) {
  SessionFolder files = test::sessionFiles();
  ResultFile& r = files.result;
  r.resumed_from = 3;
  r.remeasured = std::vector<int>{2, 5};
  r.recoveries = ResultFile::Recoveries{1, 2};
  r.truth->world_file = "truth-world.yaml";
  r.cal_offset_rad = std::array<double, 6>{0.5, 2.001890, 6.07245, 0.25, 3.5, 1e-3};
  PoseTimes measured;
  measured.pose = 1;
  measured.servo.move_s = 1.25;
  measured.servo.moves = 7;
  measured.servo.search_moves = 2;
  measured.again = true;
  measured.move_overhead_s = 2.4;
  measured.fine_point_settle_s = 0.8;
  PoseTimes skipped;
  skipped.pose = 2;
  skipped.skipped = "servo spot not found";
  r.pose_breakdown = std::vector<PoseTimes>{measured, skipped};
  const json j = toJson(r);
  EXPECT_EQ(j["pose_breakdown"][0]["servo_moves"], 7);
  EXPECT_EQ(j["pose_breakdown"][1], json::parse(R"({"pose":2,"skipped":"servo spot not found"})"));
  const ResultFile back = resultFileFromJson(j);
  EXPECT_EQ(toJson(back), j);
  ASSERT_TRUE(back.pose_breakdown);
  EXPECT_EQ(back.pose_breakdown->at(0).servo.search_moves, 2);
  EXPECT_EQ(back.pose_breakdown->at(1).skipped, "servo spot not found");
  EXPECT_EQ(back.truth->world_file, "truth-world.yaml");
  EXPECT_EQ(j["controller_cal_offset_rad"][2], 6.07245);
  ASSERT_TRUE(back.cal_offset_rad);
  EXPECT_EQ(*back.cal_offset_rad, *r.cal_offset_rad);
  // The solve itself, typed: what a reader uses.
  EXPECT_EQ(back.report.parameters.size(), r.report.parameters.size());
  EXPECT_EQ(back.report.parameters[0].value, r.report.parameters[0].value);
  EXPECT_EQ(back.report.estimate.target_mm, r.report.estimate.target_mm);
  EXPECT_NEAR(back.report.estimate.delta_rad[1], r.report.estimate.delta_rad[1], 1e-15);
}

TEST(SessionFiles, AMissingMemberIsNamedWithItsFile) {
  json result = toJson(test::sessionFiles().result);
  result.erase("converged");
  try {
    resultFileFromJson(result);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "result.json: 'converged' is missing");
  }
  json session = toJson(test::sessionFiles().session);
  session["plan"].erase("noise_mm");
  try {
    sessionFileFromJson(session);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "session.json plan: 'noise_mm' is missing");
  }
  session = toJson(test::sessionFiles().session);
  session["plan"]["poses"][1] = {1, 2, 3};
  EXPECT_THROW(sessionFileFromJson(session), InputError);
}

TEST(SessionFiles, AResultWrittenBeforeVerdictsStaysWithoutOne) {
  json result = toJson(test::sessionFiles().result);
  result.erase("verdict");
  const ResultFile r = resultFileFromJson(result);
  EXPECT_FALSE(r.verdict_recorded);
  EXPECT_EQ(toJson(r), result);
}

TEST(SessionFiles, AHandEditedPlanWithoutAPredictionPredictsNothing) {
  json session = toJson(test::sessionFiles().session);
  session["plan"].erase("predicted");
  const SessionFile s = sessionFileFromJson(session);
  ASSERT_EQ(s.plan.prediction.sigma.size(), 8u);
  EXPECT_TRUE(std::isnan(s.plan.prediction.sigma[0]));
  EXPECT_FALSE(s.plan.prediction.identifiable[0]);
}

}  // namespace
}  // namespace zerocal
