// A robot's reference as checks and restores measure against it (docs/record.md): a finished
// reference session, read from its folder (the source of truth), with what the change since it
// needs (zerocal/calib/change.h).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/change.h"
#include "zerocal/cell/robot_info.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

struct Reference {
  std::string id;
  ReferenceFit fit;             // the poses its solve used, and its solve's parameters
  std::vector<int> plan_poses;  // fit.poses[k]'s 1-based plan pose in the reference session
  RobotInfo robot;              // as its controller named itself
  // The controller's cal_offset values (rad, joints 1..6) while it measured, when recorded.
  std::optional<std::array<double, 6>> cal_offset_rad;
  double noise_mm = 0;  // the measurement sigma it was planned and solved with
};

// Reference session `id` of `store`. Throws Refused("bad_request") for an id no session has the
// form of, ("not_found") when there is no such session, ("not_a_reference") when it is not a
// finished reference whose result may be used (its verdict says why not), ("damaged") when its
// files cannot be read.
Reference loadReference(const SessionStore& store, const std::string& id);

// The latest finished reference of `store` whose verdict is usable, of the robot with this
// serial when given; empty when there is none.
std::string latestReference(const SessionStore& store, const std::string& serial = "");

// The kind to run next, in a sentence for the status (SessionStatus::suggestion): a reference
// when `latest` (latestReference's answer) is empty, else a check against it.
std::string suggestedKind(const std::string& latest);

}  // namespace zerocal::service
