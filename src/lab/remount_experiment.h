// zerocal-lab experiment remount: how far the PSD or the laser may be taken off and mounted again
// between a reference and a restore before the restore's cancellation of the link errors
// degrades, and whether the restore says so when it does (docs/simulated-cell.md, "A re-mounted
// PSD or laser").
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace zerocal::lab {

struct RemountExperimentArgs {
  int worlds = 20;
  std::uint64_t seed0 = 1;
  bool json = false;
  bool ideal_world = false;
  std::vector<std::string> overrides;  // daemon configuration keys, section.key=value
  // The re-mounts measured, each as its size in a direction drawn per world and size: the PSD
  // moved (mm) and turned (deg) on its base, the laser moved (mm) and its beam turned (deg).
  std::vector<double> psd_moved_mm{0.005, 0.01, 0.02, 0.05, 0.1, 0.5, 1.0};
  std::vector<double> psd_turned_deg{0.1, 0.5, 2.0};
  std::vector<double> laser_moved_mm{0.02, 0.1, 0.5};
  std::vector<double> laser_turned_deg{0.002, 0.01, 0.05, 0.2};
  // Both sessions as warm (backend.sim_warm_s, s), so that only the re-mount differs; the
  // restore's zero change drawn as `experiment life` draws it.
  double warm_s = 3600;
  double restore_min_deg = 0.05, restore_max_deg = 1.0;
  // What makes a restore's value wrong: an offset beyond this many of its reported sigmas.
  double max_sigmas = 3.0;
  // Within the tolerance a re-mount keeps the restore's figures: RMS error, usable share, and
  // the 95% intervals' coverage (90%: two binomial standard deviations of 80 intervals below 95%).
  double max_rms_deg = 0.003;
  double min_usable_share = 0.95;
  double min_coverage = 0.90;
  CLI::App* cmd = nullptr;
};

// Adds `remount` to `experiment`.
void addRemountExperiment(CLI::App& experiment, RemountExperimentArgs& args);

// Returns 0 when every restore completed and none offered a wrong value as usable (at any
// re-mount: a re-mount beyond the tolerance must be told, not taken), kRequirementNotMet
// (cell_experiment.h) otherwise; throws ConfigError for a bad override or argument.
int runRemountExperiment(const RemountExperimentArgs& args);

}  // namespace zerocal::lab
