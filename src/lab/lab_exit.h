// The exit codes of zerocal-lab's commands (docs/cli.md); 7 (a requirement of an experiment does
// not hold) is the experiments' (cell_experiment.h).
#pragma once

namespace zerocal::lab {

enum LabExit {
  kOk = 0,
  kFailure = 1,
  kBadInput = 2,
  kNotConverged = 3,
  kNotIdentifiable = 4,
  kRefused = 8,  // solved, but the verdict refuses the result
};

}  // namespace zerocal::lab
