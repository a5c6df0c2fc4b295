// What a plan will cost in cell time, told before anything moves: the seconds a pose has cost
// this daemon's latest sessions (result.json's cell_time_s over its poses), times the plan's
// poses. Connecting, re-measured poses and the solve are in those seconds, as in the result's
// cell time; a technician's PSD move between placements is not.
#pragma once

#include "zerocal/results/plan.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

struct CellTimePerPose {
  double seconds = 0;  // pooled over the sessions: their cell time over their poses
  int sessions = 0;    // how many it is from; 0: none to go by
};

// From the latest `count` finished sessions of `store` with a cell time that ran from their
// first pose (a resumed one counts only since its restart, and is left out). A result that
// cannot be read counts for nothing.
CellTimePerPose cellTimePerPose(const SessionStore& store, int count = 5);

// Sets `plan`'s predicted cell time from `per_pose` (nothing when it has no session to go by).
void predictCellTime(Plan& plan, const CellTimePerPose& per_pose);

}  // namespace zerocal::service
