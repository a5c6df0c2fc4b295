// Which robot a controller says it drives: what a session's result records of its cell
// (result.json "cell.controller"), so that offsets are never entered on another robot.
#pragma once

#include <string>

namespace zerocal {

// Identification reported by the controller (code 98).
struct RobotInfo {
  std::string serial;
  std::string software_version;
  std::string robot_type;
};

}  // namespace zerocal
