// Plans the optimal planner made once, stored as joint-set files under tests/data/plans/ (its
// README says how each was made and how to make it again). The planner takes about two seconds a
// plan; a test whose subject is not the planner loads its plan here instead.
#pragma once

#include <string>
#include <vector>

#include "zerocal/io/joint_set.h"

namespace zerocal::testing {

// tests/data/plans/<name>.csv in the source tree.
inline std::string storedPlanPath(const std::string& name) {
  return std::string(ZEROCAL_TEST_DATA_DIR) + "/plans/" + name + ".csv";
}

// Throws InputError when the file is missing or malformed.
inline std::vector<Pose> storedPlan(const std::string& name) {
  return readJointSet(storedPlanPath(name));
}

}  // namespace zerocal::testing
