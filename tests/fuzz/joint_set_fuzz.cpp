// Fuzz target: the joint-set CSV (parseJointSet). What it accepts must write out and read back
// to as many poses (formatJointSet), as `zerocal plan --out` and a later solve rely on.
#include "fuzz_input.h"
#include "zerocal/error.h"
#include "zerocal/io/joint_set.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<zerocal::Pose> poses;
  try {
    poses = zerocal::parseJointSet(zerocal::fuzz::text(data, size), "fuzz.csv");
  } catch (const zerocal::InputError&) {
    return 0;
  }
  const auto back = zerocal::parseJointSet(zerocal::formatJointSet(poses), "written.csv");
  if (back.size() != poses.size()) __builtin_trap();
  return 0;
}
