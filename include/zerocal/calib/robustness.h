// Monte Carlo of what a result's honesty is worth, on the Table II scenario (experiment.h):
// how often the 95% intervals contain the truth when the noise is larger than the solver was
// told, and how often one gross error in a session is found, named and left out.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace zerocal {

struct CoverageOptions {
  int repeats = 500;
  std::uint64_t seed = 1;
  // The recording's noise is this many times the noise given to the solver.
  double noise_factor = 1.5;
  std::vector<int> pose_counts = {8, 16};
};

struct CoverageResult {
  int poses = 0;
  double noise_factor = 1;
  int estimates = 0;  // offsets judged (repeats x 4, less the runs that did not converge)
  // Fraction of the offsets whose reported 95% interval contains the truth, and the same for the
  // interval the given noise alone would give (sigma not rescaled, normal quantile).
  double coverage = 0, coverage_unscaled = 0;
  double mean_noise_scale = 0;
  int usable_runs = 0;  // verdict usable
};

std::vector<CoverageResult> runCoverage(const CoverageOptions& options);

enum class GrossErrorKind {
  kNone,   // a clean session: what is found is a false alarm
  kSpot,   // the spot recorded spot_error_mm off where the beam was (stray light)
  kJoint,  // one joint of 2..5 read joint_error_deg off (recorded before the robot settled)
};
std::string grossErrorName(GrossErrorKind kind);

struct GrossErrorOptions {
  int repeats = 200;
  std::uint64_t seed = 1;
  std::vector<int> pose_counts = {8, 10, 12, 14, 16};
  double spot_error_mm = 2.0;
  double joint_error_deg = 0.05;
};

struct GrossErrorResult {
  int poses = 0;
  GrossErrorKind kind = GrossErrorKind::kNone;
  int runs = 0;
  int named = 0;    // the corrupted pose (and only it) left out, verdict usable
  int wrong = 0;    // another pose left out, or more than the corrupted one
  int refused = 0;  // verdict not usable (among them: ambiguous, too few poses to check)
  int missed = 0;   // nothing found, verdict usable
  // Among the usable results: how many have every offset within 3 reported sigmas of the truth.
  int usable_within_3_sigma = 0;
};

std::vector<GrossErrorResult> runGrossErrors(const GrossErrorOptions& options);

}  // namespace zerocal
