// zerocal-lab experiment life: a robot's life on the simulated cell, one per seeded world, with
// the daemon's own session manager: a reference, a check with nothing changed, a check with one
// zero moved a little, a restore with one zero moved (a motor replaced) and its online apply,
// checked against the figures of issue 29 (docs/simulated-cell.md, "A robot's life, measured").
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace zerocal::lab {

struct LifeExperimentArgs {
  int worlds = 30;
  std::uint64_t seed0 = 1;
  bool json = false;
  bool ideal_world = false;            // the seeds' ideal worlds (no links' errors, no warming)
  std::vector<std::string> overrides;  // daemon configuration keys, section.key=value
  // The arm's thermal state at each session's start (backend.sim_warm_s, s): the reference taken
  // warm (the robot had worked before), the checks as warm as it, the restore cold (the robot
  // just switched on after its repair), so that the two differ as the figures ask.
  double reference_warm_s = 3600;
  double check_warm_s = 3600;
  double restore_warm_s = 0;
  // The zero moved for the second check (deg, joint 2 + seed % 4, its sign alternating), and the
  // range a restore's change is drawn from (deg, its joint and sign drawn too).
  double check_change_deg = 0.02;
  double restore_min_deg = 0.05, restore_max_deg = 1.0;
  // The requirements (issue 29, "Figures").
  double max_restore_rms_deg = 0.003;
  double max_sigmas = 3.0;
  double min_coverage = 0.93, max_coverage = 0.97;
  double min_usable_share = 0.95;
  double max_restore_cell_time_s = 90;
  double min_pass_share = 0.95;
  double min_named_share = 0.95;
  double max_check_cell_time_s = 30;
  double max_after_apply_rms_deg = 0.003;
  CLI::App* cmd = nullptr;
};

// Adds `life` to `experiment`.
void addLifeExperiment(CLI::App& experiment, LifeExperimentArgs& args);

// Returns 0 when every requirement holds, kRequirementNotMet (cell_experiment.h) when one does not
// or a session did not complete; throws ConfigError for a bad override or argument.
int runLifeExperiment(const LifeExperimentArgs& args);

}  // namespace zerocal::lab
