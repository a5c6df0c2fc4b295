// A calibration run on the simulated cell (real client over TCP, real USB protocol code, real
// journal on disk), interrupted and resumed from its journal.
#include "zerocal/session/calibration_run.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>

#include "stored_plan.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/sim/simulated_rig.h"

namespace zerocal {
namespace {

// The ideal world: these tests check the run's journal and resumption by the accuracy of its
// result, which the realistic world's model errors would blur (docs/simulated-cell.md).
sim::SimulatedRig rigFor(std::uint64_t seed) {
  sim::SimulatedCellOptions o = sim::seededCellOptions(seed, WorldKind::kIdeal);
  o.world.noise.repeatability_deg = 5e-4;
  return sim::SimulatedRig(std::move(o));
}

// A fresh folder, removed with everything in it when the test ends.
struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-run-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

TEST(CalibrationRun, InterruptedRunResumesFromItsJournalWithoutLosingOrRepeatingAPose) {
  sim::SimulatedRig rig(rigFor(24));
  const World& world = rig.cell.world();
  const sim::SessionKnowledge given = sim::knowledgeOf(world);
  const CellModel& knowledge = given.cell;
  const Eigen::Vector3d& taught = given.taught_centre;
  const std::vector<Pose> plan = testing::storedPlan("ideal-24");  // the optimal planner's
  RunSettings settings;
  settings.servo.stop = servo::ServoStop::kZone;
  settings.solve.noise_mm = 0.010;  // the simulated robot's repeatability at the PSD
  const TempDir dir;
  const std::string journal_path = dir.path + "/journal.jsonl";

  // First attempt: stopped (as by an abort or a crash) after three poses.
  std::atomic<bool> abort{false};
  {
    Journal journal(journal_path);
    CalibrationRun run(knowledge, taught, plan, settings, journal);
    run.on_pose = [&](const PoseRecord& r) { abort = r.index == 2; };
    const RunOutcome out = run.run(rig.client, rig.psd, rig.cell, abort);
    EXPECT_EQ(out.state, RunState::kAborted);
    EXPECT_EQ(out.records.size(), 3u);
    EXPECT_FALSE(out.report.has_value());
  }
  // A crash mid-write leaves half a line behind: it must be dropped, not read as a pose.
  { std::ofstream(journal_path, std::ios::app) << "{\"index\": 3, \"joints_deg\": [1.0, 2."; }

  abort = false;
  Journal journal(journal_path);
  EXPECT_EQ(journal.nextIndex(), 3);
  EXPECT_FALSE(journal.dropped().empty());
  CalibrationRun run(knowledge, taught, plan, settings, journal);
  const RunOutcome out = run.run(rig.client, rig.psd, rig.cell, abort);
  ASSERT_EQ(out.state, RunState::kCompleted) << out.message;
  EXPECT_EQ(out.resumed_from, 3);
  ASSERT_EQ(out.records.size(), plan.size());
  const JournalContents on_disk = readJournal(journal_path);
  ASSERT_EQ(on_disk.records.size(), plan.size());
  for (std::size_t i = 0; i < on_disk.records.size(); ++i)
    EXPECT_EQ(on_disk.records[i].index, static_cast<int>(i));

  ASSERT_TRUE(out.report.has_value());
  ASSERT_TRUE(out.report->converged);
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& e = out.report->parameters[k];
    EXPECT_LE(std::abs(e.value - world.true_offsets_deg[k + 1]), 3 * e.sigma) << e.name;
  }
}

TEST(CalibrationRun, RefusesAJournalLongerThanThePlan) {
  const TempDir dir;
  const std::string path = dir.path + "/journal.jsonl";
  {
    Journal journal(path);
    for (int i = 0; i < 3; ++i) {
      PoseRecord r;
      r.index = i;
      journal.append(r);
    }
  }
  Journal journal(path);
  CellModel knowledge;
  std::vector<Pose> plan(2);
  EXPECT_THROW(CalibrationRun(knowledge, Eigen::Vector3d::Zero(), plan, {}, journal), InputError);
}

// A plan's placements come 1, 2, ... in turn: the technician is guided forward only. The run
// waits for the next one only once every pose of the one before is recorded, and a placement
// is journalled only while awaited.
TEST(CalibrationRun, APlanAtSeveralPlacementsIsGuidedForwardOnlyAndWaitsBetweenThem) {
  const sim::SessionKnowledge given = sim::knowledgeOf(randomWorld(5, WorldKind::kIdeal));
  const std::vector<Pose> plan = testing::storedPlan("ideal-5-2-placements");
  const TempDir dir;
  Journal journal(dir.path + "/journal.jsonl");
  const auto at = [&](std::vector<int> placements) {
    std::vector<Pose> poses;
    for (int p : placements) poses.push_back({plan[poses.size()].q_deg, std::nullopt, 0, p});
    return poses;
  };
  for (const std::vector<int>& wrong :
       {std::vector<int>{1, 1, 1, 3, 3, 3}, {1, 1, 2, 2, 1, 1}, {2, 2, 2, 2, 2, 2}})
    EXPECT_THROW(CalibrationRun(given.cell, given.taught_centre, at(wrong), {}, journal),
                 InputError);

  CalibrationRun run(given.cell, given.taught_centre, plan, {}, journal);
  EXPECT_EQ(run.awaitedPlacement(), 0);  // placement 1's poses first
  EXPECT_THROW(run.placeNext(Eigen::Vector3d(600, 650, 600)), InputError);
  for (int i = 0; i < 8; ++i) {
    PoseRecord r;
    r.index = i;
    r.joints_deg = plan[i].q_deg;
    journal.append(r);
  }
  EXPECT_EQ(run.awaitedPlacement(), 2);
  EXPECT_THROW(run.placeNext(Eigen::Vector3d(NAN, 650, 600)), InputError);
  run.placeNext(Eigen::Vector3d(600, 650, 600));
  EXPECT_EQ(journal.placement(), 2);
  EXPECT_EQ(run.awaitedPlacement(), 0);
  EXPECT_THROW(run.placeNext(Eigen::Vector3d(600, 650, 600)), InputError);
  // The solver is given each pose's placement.
  PoseRecord r;
  r.index = 8;
  r.placement = 2;
  journal.append(r);
  EXPECT_EQ(posesOf(journal.records()).back().placement, 2);
  EXPECT_EQ(posesOf(journal.records()).front().placement, 1);
  // And each pose's journal line, for the solve's residuals and messages: pose 9 follows the
  // eight of placement 1 and the placement line.
  EXPECT_EQ(posesOf(journal.records()).front().source_line, 1);
  EXPECT_EQ(posesOf(journal.records()).back().source_line, 10);
}

}  // namespace
}  // namespace zerocal
