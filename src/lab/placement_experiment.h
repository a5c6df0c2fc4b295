// zerocal-lab experiment placements: calibrations with several PSD placements on seeded simulated
// worlds, beside the same worlds calibrated from one placement.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace zerocal::lab {

struct PlacementExperimentArgs {
  int worlds = 30;
  std::uint64_t seed0 = 1;
  int placements = 3;       // PSD placements of the several-placement session
  int poses = 12;           // per placement; the one-placement session has them all at one
  double noise_mm = 0.020;  // the measurement sigma given to the solve (the daemon's)
  // The gravity sag's tolerances of joints 2 and 3 (or one for both) at the largest torque,
  // counted when the compliance is not identified; empty: the robot file's.
  std::vector<double> model_sag_deg;
  bool identify_compliance = false;
  // One gross error per session at a random pose: "none", "spot" (the reading gross_spot_mm off
  // in a random direction) or "joint" (one of joints 2..5 recorded gross_joint_deg off).
  std::string gross = "none";
  double gross_spot_mm = 0.5;
  double gross_joint_deg = 0.05;
  bool ideal_world = false;
  bool without_sag = false;  // the realistic world less its gravity sag (what the sag costs)
  // The realistic world's link errors times this (2.5: links worse than the robot file admits).
  double link_scale = 1.0;
  bool json = false;
  // The requirements of the several-placement sessions.
  double max_rms_deg = 0.005;
  double max_sigmas = 3.0;
  CLI::App* cmd = nullptr;
};

void addPlacementExperiment(CLI::App& experiment, PlacementExperimentArgs& args);

// Returns 0 when the requirements hold, kRequirementNotMet (cell_experiment.h) when one does not.
int runPlacementExperiment(const PlacementExperimentArgs& args);

}  // namespace zerocal::lab
