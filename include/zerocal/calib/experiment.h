// Simulated recordings and the Monte Carlo reproduction of the paper's Table II.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"

namespace zerocal {

// What a perfect PSD servo would record on a robot whose true parameters are `truth`: for each
// planned pose, the controller joints near it for which the true laser line passes through the
// true target plus a localisation error drawn uniformly within +-half_width_mm on each base
// axis (the paper's model; its per-axis sigma is half_width / sqrt(3)). Throws InputError when
// a pose cannot be servoed.
std::vector<Pose> simulateRecording(const CellModel& cell, const CalibrationParameters& truth,
                                    const std::vector<Pose>& planned, double half_width_mm,
                                    std::mt19937_64& rng);

// The scenario of calibration-math.md section 5: IRB1600, laser along flange x through the
// origin, true offsets (-0.4, 0.5, -0.7, -0.5) deg, target P1 = (900, -50, 400) mm, uniform
// +-0.05 mm localisation error, 8 poses.
struct Table2Scenario {
  CellModel cell;
  CalibrationParameters truth;
  double half_width_mm = 0.05;
  int poses = 8;
};
Table2Scenario table2Scenario();

struct ParameterStats {
  std::string name;
  double truth = 0;
  double mean_error = 0;   // over the repeats, same unit as the parameter (deg for offsets)
  double std = 0;          // sample standard deviation of the estimates
  double crb = 0;          // Cramer-Rao bound (one sigma) at the true parameters
  bool has_paper = false;  // the paper's Table II figures for this pattern and parameter
  double paper_mean_error = 0, paper_std = 0;
};

struct ScenarioResult {
  Pattern pattern = Pattern::kI;
  CostKind cost = CostKind::kMaximumLikelihood;
  std::vector<Pose> poses;             // the planned (nominal) poses
  std::vector<ParameterStats> stats;   // the 8 identified parameters
  double rms_error_deg = 0;            // RMS of all delta2..delta5 errors over all repeats
  double predicted_rms_sigma_deg = 0;  // RMS of the CRB over delta2..delta5
  int not_identifiable_runs = 0;       // repeats whose report flagged any offset
  int failed_runs = 0;                 // repeats whose solve did not converge
  double mean_solve_ms = 0;
};

struct ExperimentOptions {
  int repeats = 1000;
  std::uint64_t seed = 1;
  std::vector<Pattern> patterns = {Pattern::kI, Pattern::kII, Pattern::kOptimal};
  std::vector<CostKind> costs = {CostKind::kMaximumLikelihood, CostKind::kPairwise};
};

std::vector<ScenarioResult> runTable2(const ExperimentOptions& options);

}  // namespace zerocal
