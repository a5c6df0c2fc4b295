// zerocal-lab experiment apply: on seeded simulated cells, calibrate, apply online, verify by a
// second calibration; with --wrong-sign J, check that the rollback names joint J.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <ostream>

namespace zerocal::lab {

struct ApplyExperimentArgs {
  int worlds = 10;
  std::uint64_t seed0 = 1;
  int poses = 0;             // the command line sets the daemon's session.poses
  int wrong_sign_joint = 0;  // 2..5: that joint's transmission sign flipped in the configuration
  double required_deg = 0.003;
  CLI::App* cmd = nullptr;
};

// Adds `apply` to `experiment`.
void addApplyExperiment(CLI::App& experiment, ApplyExperimentArgs& args);

// 0 when the experiment's requirements hold, 7 when not, 1 when a calibration failed.
int runApplyExperiment(const ApplyExperimentArgs& args, std::ostream& out, std::ostream& err);

}  // namespace zerocal::lab
