// What the single- and several-placement solves share (src/calib only).
#pragma once

#include <ceres/ceres.h>

#include <functional>
#include <string>
#include <vector>

#include "zerocal/calib/solver.h"

namespace zerocal::detail {

// Abandons a solve when SolveOptions::cancelled says so.
class CancelCallback : public ceres::IterationCallback {
 public:
  explicit CancelCallback(const std::function<bool()>& cancelled) : cancelled_(cancelled) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return cancelled_ && cancelled_() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<bool()>& cancelled_;
};

// Ceres' options of every solve: dense QR, tight tolerances, one thread, silent, the caller's
// iteration limit, and `cancel` polled each iteration (it must outlive the solve).
ceres::Solver::Options solverOptions(const SolveOptions& options, CancelCallback* cancel);

// The gates: any reason here and the result is not offered for use.
Verdict judge(const SolveReport& r, const SolveOptions& o,
              const std::vector<std::string>& gross_problems);

// Per pose, the earlier pose it repeats exactly (joints, reading and placement), or -1.
std::vector<int> findDuplicates(const std::vector<Pose>& poses);
// Throws InputError when fewer than kMinimumPoses of the poses are distinct.
void throwUnlessEnoughDistinct(const std::vector<Pose>& poses, const std::vector<int>& duplicate_of,
                               int distinct);

// Sets noise_mm, noise_estimated, chi2_per_dof, chi2_p_value and noise_scale from the sum of
// squared misses (mm^2) and report.dof, as docs/maths.md section 5 says.
void applyNoise(SolveReport& report, const SolveOptions& options, double rss_mm2);
// The 95% interval's half-width in sigmas: 1.96, or Student's t(dof) when the sigma in force
// comes from the residuals.
double intervalQuantile(const SolveReport& report);

// A report with what the options and the poses say before any fit: the cost, whether the
// readings are used (every pose has one and the options want them), the pose count, the
// required accuracy.
SolveReport startReport(const std::vector<Pose>& poses, const SolveOptions& options);

std::string fixedText(double v, int precision);
// "pose 3 (line 5)".
std::string poseLabel(const std::vector<Pose>& poses, int i);

// solve() for poses at two or more PSD placements (docs/maths.md section 8).
SolveReport solveMultiPlacement(const CellModel& cell, const std::vector<Pose>& poses,
                                const SolveOptions& options);

}  // namespace zerocal::detail
