#include "zerocal/calib/robustness.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "zerocal/calib/experiment.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

std::vector<Pose> planFor(const Table2Scenario& sc, int poses, double sigma) {
  PlanOptions po;
  po.poses = poses;
  po.noise_mm = sigma;
  return planPoses(sc.cell, sc.truth.target_mm, po).poses;
}

bool withinSigmas(const SolveReport& r, const CalibrationParameters& truth, double sigmas) {
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& p = r.parameters[k];
    if (!p.identifiable ||
        !(std::abs(p.value - truth.delta_rad[k] * kRadToDeg) <= sigmas * p.sigma))
      return false;
  }
  return true;
}

}  // namespace

std::vector<CoverageResult> runCoverage(const CoverageOptions& options) {
  if (options.repeats < 1) throw InputError("the experiment needs at least 1 repeat");
  if (!(options.noise_factor > 0)) throw InputError("the noise factor must be positive");
  const Table2Scenario sc = table2Scenario();
  const double given = sc.half_width_mm / std::sqrt(3.0);
  std::vector<CoverageResult> out;
  for (const int n : options.pose_counts) {
    const auto planned = planFor(sc, n, given);
    std::mt19937_64 rng(options.seed);
    CoverageResult c;
    c.poses = n;
    c.noise_factor = options.noise_factor;
    int covered = 0, covered_unscaled = 0;
    double scale_sum = 0;
    for (int rep = 0; rep < options.repeats; ++rep) {
      const auto recorded = simulateRecording(sc.cell, sc.truth, planned,
                                              sc.half_width_mm * options.noise_factor, rng);
      SolveOptions so;
      so.noise_mm = given;
      const SolveReport r = solve(sc.cell, recorded, so);
      if (!r.converged) continue;
      scale_sum += r.noise_scale;
      c.usable_runs += r.verdict.usable ? 1 : 0;
      for (int k = 0; k < kOffsetCount; ++k) {
        const ParameterEstimate& p = r.parameters[k];
        const double error = std::abs(p.value - sc.truth.delta_rad[k] * kRadToDeg);
        ++c.estimates;
        covered += error <= p.ci95_high - p.value ? 1 : 0;
        covered_unscaled += error <= 1.959963984540054 * p.sigma / r.noise_scale ? 1 : 0;
      }
    }
    const double runs = std::max(1, c.estimates / kOffsetCount);
    c.coverage = c.estimates ? static_cast<double>(covered) / c.estimates : 0;
    c.coverage_unscaled = c.estimates ? static_cast<double>(covered_unscaled) / c.estimates : 0;
    c.mean_noise_scale = scale_sum / runs;
    out.push_back(c);
  }
  return out;
}

std::string grossErrorName(GrossErrorKind kind) {
  switch (kind) {
    case GrossErrorKind::kNone:
      return "none";
    case GrossErrorKind::kSpot:
      return "spot";
    case GrossErrorKind::kJoint:
      return "joint";
  }
  return "?";
}

std::vector<GrossErrorResult> runGrossErrors(const GrossErrorOptions& options) {
  if (options.repeats < 1) throw InputError("the experiment needs at least 1 repeat");
  const Table2Scenario sc = table2Scenario();
  const double sigma = sc.half_width_mm / std::sqrt(3.0);
  std::vector<GrossErrorResult> out;
  for (const int n : options.pose_counts) {
    const auto planned = planFor(sc, n, sigma);
    for (const GrossErrorKind kind :
         {GrossErrorKind::kNone, GrossErrorKind::kSpot, GrossErrorKind::kJoint}) {
      std::mt19937_64 rng(options.seed);
      std::uniform_real_distribution<double> noise(-sc.half_width_mm, sc.half_width_mm);
      std::uniform_int_distribution<int> which_pose(0, n - 1), which_joint(1, 4);
      std::normal_distribution<double> direction;
      GrossErrorResult g;
      g.poses = n;
      g.kind = kind;
      for (int rep = 0; rep < options.repeats; ++rep) {
        const int bad = which_pose(rng);
        std::vector<Pose> recorded;
        for (int i = 0; i < n; ++i) {
          Eigen::Vector3d miss(noise(rng), noise(rng), noise(rng));
          if (kind == GrossErrorKind::kSpot && i == bad) {
            const Eigen::Vector3d d(direction(rng), direction(rng), direction(rng));
            miss += options.spot_error_mm * d.normalized();
          }
          const auto q = servoOnto(sc.cell, sc.truth, sc.truth.target_mm + miss, planned[i].q_deg);
          if (!q)
            throw InputError("simulated pose " + std::to_string(i + 1) + " cannot be servoed");
          recorded.push_back({*q, {}, i + 1});
        }
        if (kind == GrossErrorKind::kJoint)
          recorded[bad].q_deg[which_joint(rng)] += options.joint_error_deg;
        SolveOptions so;
        so.noise_mm = sigma;
        const SolveReport r = solve(sc.cell, recorded, so);
        ++g.runs;
        int left_out = 0;
        bool bad_left_out = false;
        for (int i = 0; i < n; ++i)
          if (r.poses[i].outlier) ++left_out, bad_left_out = bad_left_out || i == bad;
        const bool corrupted = kind != GrossErrorKind::kNone;
        if (!r.verdict.usable)
          ++g.refused;
        else if (corrupted && bad_left_out && left_out == 1)
          ++g.named;
        else if (left_out > 0)
          ++g.wrong;
        else
          ++g.missed;
        if (r.verdict.usable && withinSigmas(r, sc.truth, 3.0)) ++g.usable_within_3_sigma;
      }
      out.push_back(g);
    }
  }
  return out;
}

}  // namespace zerocal
