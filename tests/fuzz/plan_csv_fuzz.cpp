// Fuzz target: a plan file (session.plan_file, `plan: file` over the control port) read as the
// daemon reads it: from a file (readJointSet), then every pose checked against the arm's limits.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_input.h"
#include "zerocal/error.h"
#include "zerocal/io/joint_set.h"
#include "zerocal/model/builtin.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // One scratch file for every input, removed when the program ends.
  struct ScratchFile {
    std::string path;
    ScratchFile() {
      char name[] = "/tmp/zerocal-fuzz-plan-XXXXXX";
      const int fd = ::mkstemp(name);
      if (fd < 0) std::abort();
      ::close(fd);
      path = name;
    }
    ~ScratchFile() { std::remove(path.c_str()); }
  };
  static const ScratchFile scratch;
  const std::string& path = scratch.path;
  static const zerocal::Robot robot = zerocal::builtinIrb1600();
  std::FILE* out = std::fopen(path.c_str(), "wb");
  if (!out || std::fwrite(data, 1, size, out) != size || std::fclose(out) != 0) std::abort();
  try {
    for (const zerocal::Pose& pose : zerocal::readJointSet(path))
      robot.limitViolation(pose.q_deg, 1.0);
  } catch (const zerocal::InputError&) {
  }
  return 0;
}
