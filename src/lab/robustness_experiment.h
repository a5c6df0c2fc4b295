// zerocal-lab experiment coverage | gross-errors: what the verdict and the intervals are worth
// (zerocal/calib/robustness.h), as text or JSON.
#pragma once

#include <CLI/CLI.hpp>

#include "zerocal/calib/robustness.h"

namespace zerocal::lab {

struct RobustnessExperimentArgs {
  CoverageOptions coverage;
  GrossErrorOptions gross;
  bool json = false;
  CLI::App* coverage_cmd = nullptr;
  CLI::App* gross_cmd = nullptr;
};

// Adds both subcommands to `experiment`.
void addRobustnessExperiments(CLI::App& experiment, RobustnessExperimentArgs& args);

// Runs whichever was parsed; returns the exit code (0), or -1 when neither was.
int runRobustnessExperiment(const RobustnessExperimentArgs& args);

}  // namespace zerocal::lab
