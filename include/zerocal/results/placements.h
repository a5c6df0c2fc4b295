// The PSD placements a pose list aims at: what a plan read back from session.json counts, and
// what the solver and planner split their poses by.
#pragma once

#include <vector>

#include "zerocal/io/joint_set.h"

namespace zerocal {

// The distinct placement numbers of the poses, ascending.
std::vector<int> placementsOf(const std::vector<Pose>& poses);
inline int placementCount(const std::vector<Pose>& poses) {
  return static_cast<int>(placementsOf(poses).size());
}

}  // namespace zerocal
