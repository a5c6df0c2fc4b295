// The shipped IRB 1600 as a robot file that states its model exact (model_tolerance 0 and 0):
// for the tests whose simulated arm is the robot file's exactly (an ideal world behind a
// configured cell), where the solve has no link error to count.
#pragma once

#include <fstream>
#include <string>

#include "zerocal/model/builtin.h"
#include "zerocal/model/robot.h"

namespace zerocal::testing {

// Writes the file at `path` and returns the path.
inline std::string writeExactRobot(const std::string& path) {
  Robot robot = builtinIrb1600();
  robot.tolerance = {};
  std::ofstream(path) << robotYaml(robot, "the shipped IRB 1600, its model stated exact");
  return path;
}

}  // namespace zerocal::testing
