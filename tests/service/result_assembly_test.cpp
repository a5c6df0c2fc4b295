// result.json from a run's outcome, without a thread or a cell: what each member is made of.
#include "zerocal/service/result_assembly.h"

#include <gtest/gtest.h>

#include <cmath>

namespace zerocal::service {
namespace {

SolveReport solved() {
  SolveReport report;
  report.converged = true;
  for (int k = 0; k < kOffsetCount; ++k) {
    ParameterEstimate p;
    p.name = "delta" + std::to_string(k + 2) + "_deg";
    p.value = 0.1 * (k + 1);
    p.sigma = 0.001 * (k + 1);
    p.identifiable = k != 2;  // delta4 withheld
    report.parameters.push_back(p);
  }
  return report;
}

// Plan poses 1..3: 1 measured, 2 skipped, 3 measured; then pose 1 measured again.
RunOutcome completedRun() {
  RunOutcome outcome;
  outcome.state = RunState::kCompleted;
  outcome.report = solved();
  outcome.resumed_from = 2;
  outcome.reconnects = 1;
  outcome.reopens = 2;
  outcome.remeasured = {0};
  PoseRecord first;
  first.index = 0;
  first.servo.moves = 4;
  first.servo.final_error_um = 3;
  PoseRecord skipped;
  skipped.index = 1;
  skipped.skipped = "spot not found";
  PoseRecord third;
  third.index = 2;
  third.servo.moves = 1;
  PoseRecord again = first;
  again.index = 3;
  again.remeasure_of = 0;
  again.servo.moves = 2;
  outcome.records = {first, skipped, third, again};
  return outcome;
}

RunFacts facts() {
  RunFacts f;
  f.cell.controller.robot_type = "IRB 1600-10/1.45";
  f.cell.controller.serial = "1600-504321";
  f.cell.psd_map = "psd-map.txt, fingerprint 0123";
  f.cal_offset_rad = std::array<double, 6>{1, 2, 3, 4, 5, 6};
  f.cell_time_s = 321.5;
  f.finished_unix_s = 1796137200;
  return f;
}

TEST(AssembleResult, TheSolveTheRunsCountsAndTheFactsGoIntoTheResult) {
  const RunOutcome outcome = completedRun();
  const ResultFile r = assembleResult("20261203T120000Z", outcome, facts());
  EXPECT_EQ(r.session, "20261203T120000Z");
  EXPECT_EQ(r.report.parameters.size(), outcome.report->parameters.size());
  EXPECT_EQ(r.report.parameters[1].value, outcome.report->parameters[1].value);
  EXPECT_EQ(r.cell_time_s, 321.5);
  EXPECT_EQ(r.resumed_from, 2);
  EXPECT_EQ(r.remeasured, std::vector<int>{1});  // 1-based plan poses
  ASSERT_TRUE(r.recoveries);
  EXPECT_EQ(r.recoveries->reconnects, 1);
  EXPECT_EQ(r.recoveries->reopens, 2);
  ASSERT_TRUE(r.cell);
  EXPECT_EQ(r.cell->controller.serial, "1600-504321");
  EXPECT_EQ(r.cell->psd_map, "psd-map.txt, fingerprint 0123");
  EXPECT_EQ(r.cal_offset_rad, facts().cal_offset_rad);
  EXPECT_EQ(r.finished_unix_s, 1796137200);
  EXPECT_FALSE(r.zerocal_version.empty());
  EXPECT_FALSE(r.truth);  // not a simulated cell
}

TEST(AssembleResult, ThePoseBreakdownHasEveryJournalledPoseWithTheMovesCost) {
  RunFacts f = facts();
  f.move_overhead = MoveOverhead{0.25, 0.5};
  const ResultFile r = assembleResult("20261203T120000Z", completedRun(), f);
  ASSERT_TRUE(r.pose_breakdown);
  const std::vector<PoseTimes>& poses = *r.pose_breakdown;
  ASSERT_EQ(poses.size(), 4u);
  EXPECT_EQ(poses[0].pose, 1);
  EXPECT_FALSE(poses[0].again);
  EXPECT_EQ(poses[0].servo.moves, 4);
  // The planned move and each servo move pay the controller's cost.
  EXPECT_EQ(poses[0].move_overhead_s, 5 * 0.25);
  EXPECT_EQ(poses[0].fine_point_settle_s, 5 * 0.5);
  EXPECT_EQ(poses[1].pose, 2);
  EXPECT_EQ(poses[1].skipped, "spot not found");
  EXPECT_FALSE(poses[1].move_overhead_s);  // nothing is known of a pose skipped
  EXPECT_EQ(poses[2].pose, 3);
  EXPECT_EQ(poses[3].pose, 1);  // its second measurement
  EXPECT_TRUE(poses[3].again);
  EXPECT_EQ(poses[3].move_overhead_s, 3 * 0.25);

  // Without the cost known, the breakdown has the servo's times alone.
  const ResultFile plain = assembleResult("20261203T120000Z", completedRun(), facts());
  EXPECT_FALSE(plain.pose_breakdown->at(0).move_overhead_s);
  EXPECT_FALSE(plain.pose_breakdown->at(0).fine_point_settle_s);
}

TEST(AssembleResult, ASimulatedCellsTruthIsInTheResult) {
  RunFacts f = facts();
  f.truth_deg = std::array<double, 4>{0.5, -0.25, 0.125, 1};
  f.truth_world_file = "truth-world.yaml";
  const ResultFile r = assembleResult("20261203T120000Z", completedRun(), f);
  ASSERT_TRUE(r.truth);
  EXPECT_EQ(r.truth->offsets_deg[1], -0.25);
  EXPECT_EQ(r.truth->world_file, "truth-world.yaml");

  // The world alone (a cell that knows it but not the offsets) still names the file.
  f.truth_deg.reset();
  const ResultFile world_only = assembleResult("20261203T120000Z", completedRun(), f);
  ASSERT_TRUE(world_only.truth);
  EXPECT_EQ(world_only.truth->world_file, "truth-world.yaml");
}

TEST(AchievedSigma, IsEachOffsetsSigmaAndNanWhereWithheld) {
  const std::vector<double> achieved = achievedSigma(solved());
  ASSERT_EQ(achieved.size(), static_cast<std::size_t>(kOffsetCount));
  EXPECT_EQ(achieved[0], 0.001);
  EXPECT_EQ(achieved[1], 0.002);
  EXPECT_TRUE(std::isnan(achieved[2]));
  EXPECT_EQ(achieved[3], 0.004);
}

}  // namespace
}  // namespace zerocal::service
