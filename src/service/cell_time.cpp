#include "zerocal/service/cell_time.h"

namespace zerocal::service {

CellTimePerPose cellTimePerPose(const SessionStore& store, int count) {
  const std::vector<SessionInfo> sessions = store.list();  // oldest first: ids sort by age
  double seconds = 0;
  int poses = 0;
  CellTimePerPose per_pose;
  for (auto s = sessions.rbegin(); s != sessions.rend() && per_pose.sessions < count; ++s) {
    if (!s->finished) continue;
    try {
      const ResultFile result = store.readResult(s->id);
      if (!result.cell_time_s || result.resumed_from.value_or(0) > 0 ||
          result.report.pose_count <= 0)
        continue;
      seconds += *result.cell_time_s;
      poses += result.report.pose_count;
      ++per_pose.sessions;
    } catch (const Error&) {
      continue;
    }
  }
  if (poses > 0) per_pose.seconds = seconds / poses;
  return per_pose;
}

void predictCellTime(Plan& plan, const CellTimePerPose& per_pose) {
  if (per_pose.sessions == 0) return;
  plan.prediction.cell_time_s = per_pose.seconds * static_cast<double>(plan.poses.size());
  plan.prediction.cell_time_per_pose_s = per_pose.seconds;
  plan.prediction.cell_time_sessions = per_pose.sessions;
}

}  // namespace zerocal::service
