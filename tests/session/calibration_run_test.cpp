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

}  // namespace
}  // namespace zerocal
