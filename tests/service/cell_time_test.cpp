// The cell time a plan is told before anything moves: what a pose cost the daemon's latest
// sessions, from their result.json.
#include "zerocal/service/cell_time.h"

#include <gtest/gtest.h>

#include "record_fixture.h"
#include "temp_dir.h"

namespace zerocal::service {
namespace {

TEST(CellTime, APoseCostsWhatItCostTheLatestSessionsThatRanFromTheirFirstPose) {
  const testing::TempDir dir("zerocal-cell-time");
  SessionStore store(dir.path);
  Plan plan;
  plan.poses.resize(12);
  predictCellTime(plan, cellTimePerPose(store));
  EXPECT_EQ(plan.prediction.cell_time_sessions, 0) << "no session to go by";
  EXPECT_EQ(plan.prediction.cell_time_s, 0);

  test::FinishedSession s;  // 16 poses each
  s.cell_time_s = 1600;     // the oldest: beyond the latest five
  test::makeFinishedSession(store, s);
  for (double seconds : {80.0, 96.0, 64.0, 80.0}) {
    s.cell_time_s = seconds;
    test::makeFinishedSession(store, s);
  }
  // Resumed: its cell time counts from the restart only.
  SessionFile resumed = store.create(test::plannedSession());
  ResultFile r = test::resultOf(s, resumed.id);
  r.cell_time_s = 10;
  r.resumed_from = 9;
  store.writeResult(resumed.id, r);
  // Not resumed: a journal from its first line (resumed_from 0).
  SessionFile fresh = store.create(test::plannedSession());
  r = test::resultOf(s, fresh.id);
  r.cell_time_s = 80;
  r.resumed_from = 0;
  store.writeResult(fresh.id, r);
  store.create(test::plannedSession());  // unfinished: no result yet

  const CellTimePerPose per_pose = cellTimePerPose(store);
  EXPECT_EQ(per_pose.sessions, 5);
  EXPECT_DOUBLE_EQ(per_pose.seconds, (80.0 + 96 + 64 + 80 + 80) / (5 * 16));
  predictCellTime(plan, per_pose);
  EXPECT_EQ(plan.prediction.cell_time_sessions, 5);
  EXPECT_DOUBLE_EQ(plan.prediction.cell_time_per_pose_s, 5.0);
  EXPECT_DOUBLE_EQ(plan.prediction.cell_time_s, 60.0);
  EXPECT_EQ(cellTimePerPose(store, 2).sessions, 2);
  EXPECT_DOUBLE_EQ(cellTimePerPose(store, 2).seconds, (80.0 + 80) / 32);
}

}  // namespace
}  // namespace zerocal::service
