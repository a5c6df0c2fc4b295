// Fuzz target: the robot file (parseRobot). A robot it accepts must also write out and read
// back (robotYaml), as `zerocal-lab solve --save-model` relies on.
#include "fuzz_input.h"
#include "zerocal/error.h"
#include "zerocal/model/robot.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zerocal::Robot robot;
  try {
    robot = zerocal::parseRobot(zerocal::fuzz::text(data, size), "fuzz.yaml");
  } catch (const zerocal::ConfigError&) {
    return 0;
  }
  zerocal::parseRobot(zerocal::robotYaml(robot), "written.yaml");  // throws: a finding
  return 0;
}
