// The shipped robot model compiled into the programs (config/robots/irb1600-10-145.yaml), so
// that the demo, the experiments and the simulator run with no files installed.
#pragma once

#include "zerocal/model/robot.h"

namespace zerocal {

const char* builtinIrb1600Yaml();
Robot builtinIrb1600();

}  // namespace zerocal
