// zerocal-lab experiment table2 | cell | coverage | gross-errors | placements | apply | life |
// remount: the paper's Monte Carlo, and the experiments that measure the daemon's calibration on
// seeded simulated worlds (the cell and the apply build it as zerocald does, through
// zerocal/service/daemon_setup.h).
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>

#include "apply_experiment.h"
#include "cell_experiment.h"
#include "life_experiment.h"
#include "placement_experiment.h"
#include "remount_experiment.h"
#include "robustness_experiment.h"
#include "zerocal/calib/experiment.h"

namespace zerocal::lab {

struct ExperimentCommands {
  CLI::App* experiment = nullptr;
  CLI::App* table2 = nullptr;
  ExperimentOptions table2_options;
  bool table2_json = false;
  CLI::App* cell = nullptr;
  CellExperimentArgs cell_args;
  RobustnessExperimentArgs robustness_args;
  PlacementExperimentArgs placement_args;
  ApplyExperimentArgs apply_args;
  LifeExperimentArgs life_args;
  RemountExperimentArgs remount_args;
};

// Registers `experiment` and its subcommands; `commands` must outlive the parse.
void addExperimentCommands(CLI::App& app, ExperimentCommands& commands);

// Runs the parsed one and returns its exit code, or -1 when none was parsed. A bad override
// throws ConfigError.
int runExperimentCommands(const ExperimentCommands& commands, std::ostream& out, std::ostream& err);

}  // namespace zerocal::lab
