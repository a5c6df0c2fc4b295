// What the single- and several-placement solves share (src/calib only).
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "zerocal/calib/identifiability.h"
#include "zerocal/calib/planner.h"
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

// What a solve's misses are measured against: the model (an absolute calibration, whose misfit
// is the noise or the links beyond what is stated), or a reference's poses (a change, whose
// misfit is the cell not being as the reference had it).
enum class MissesAgainst { kModel, kReference };

// The gates: any reason here and the result is not offered for use.
Verdict judge(const SolveReport& r, const SolveOptions& o,
              const std::vector<std::string>& gross_problems,
              MissesAgainst against = MissesAgainst::kModel);

// The poses at the given indices, in that order.
std::vector<Pose> subset(const std::vector<Pose>& poses, const std::vector<int>& indices);

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
SolveReport startReport(const CellModel& cell, const std::vector<Pose>& poses,
                        const SolveOptions& options);

std::string fixedText(double v, int precision);
// "pose 3 (line 5)".
std::string poseLabel(const std::vector<Pose>& poses, int i);

// A fit of a subset of the poses, for the deletion diagnostics (docs/maths.md section 5).
struct TrialFit {
  bool converged = false;
  int iterations = 0;
  Eigen::VectorXd misses_mm;    // 2 per fitted pose, in their order
  Eigen::MatrixXd jacobian_mm;  // of the misses in the identified unknowns
  // The misses' derivatives by the model parameters known only to a tolerance, times those
  // tolerances (mm); the deletion test then weighs the misses by their covariance. Empty: none.
  Eigen::MatrixXd spread_mm;
  bool beam_points_away = false;  // a fitted stand-off <= 0
  int estimate = -1;              // the caller's handle of the estimate it reached
  std::string message;            // the solver's
};
// Fits the poses `active` (indices into the given poses, ascending) from the estimate `start`.
using SubsetFitter = std::function<TrialFit(const std::vector<int>& active, int start)>;

struct GrossErrorSearch {
  std::vector<int> active;            // the poses the result rests on
  std::vector<int> left_out;          // 0-based, in the order they were left out
  std::vector<std::string> problems;  // for the verdict: what cannot be attributed
  std::vector<SuspectPose> suspects;  // chi2_without in mm^2 per degree of freedom
  std::vector<int> remeasure;         // 1-based
  int iterations = 0;                 // of the refits
  TrialFit fit;                       // of `active`
};

// The deletion diagnostics: leaves out, at most twice, the pose that does not fit the others
// while the rest can check it, and refuses what the poses cannot attribute (two poses either
// of which explains the misfit, a third misfit, too few poses). `fit` is the fit of `active`.
// cannot_leave_out (optional) says why the poses `remaining` cannot do without pose `i`
// (empty: they can).
GrossErrorSearch findGrossErrors(
    const std::vector<Pose>& poses, std::vector<int> active, TrialFit fit,
    const SolveOptions& options, const SubsetFitter& refit,
    const std::function<std::string(const std::vector<int>& remaining, int i)>& cannot_leave_out);

// The line's miss of each pose's hit point (mm, 2 per pose) at `est`.
Eigen::VectorXd poseMisses(const CellModel& cell, const std::vector<Pose>& poses,
                           const CalibrationParameters& est, bool readings);

// The misses' derivatives by each link length and twist (a, d, alpha of every joint) times its
// tolerance, mm: 2 rows per pose, 3 columns per joint (for a calibrated model, by the square root
// of its link covariance: independent combinations); with a sag tolerance and a robot file with a
// gravity model, 2 more, joints 2 and 3's compliance. What the model errors the tolerances allow
// do to the misses, one standard deviation per column: G with G G^T their covariance.
Eigen::MatrixXd linkSpread(const CellModel& cell, const std::vector<Pose>& poses,
                           const CalibrationParameters& est, bool readings,
                           const ModelTolerances& tolerances);

// The several-placement fit's consider covariance (its unknowns' units: rad, mm): what it holds
// at nominal but knows only to a tolerance moves the identified unknowns by S = unit_cov J^T G.
// G: the link errors the poses do not identify (length_mm, angle_deg each) and, when the
// compliance is not identified and the robot has a gravity model, the sag of joints 2 and 3
// (sag_deg at the largest torque: theta_j moves by c_j tau_j(q), so its column is delta_j's times
// the pose's torque). `jac` the Jacobian of the poses `used` (any noise scale), `unit_cov` the
// pseudo-inverse of its information (the base covariance, zeros where not identified).
Eigen::MatrixXd placementModelCovariance(const CellModel& cell, const std::vector<Pose>& used,
                                         const PlacementLayout& layout, const BaseParameters& base,
                                         const Eigen::MatrixXd& jac,
                                         const Eigen::MatrixXd& unit_cov,
                                         const ModelTolerances& tolerances);

// solve() for poses at two or more PSD placements (docs/maths.md section 8).
SolveReport solveMultiPlacement(const CellModel& cell, const std::vector<Pose>& poses,
                                const SolveOptions& options);

}  // namespace zerocal::detail
