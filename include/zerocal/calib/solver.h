// Identification of delta2..delta5 and the laser line from recorded poses (Ceres), with the
// uncertainty and identifiability an operator needs to judge the result.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"

namespace zerocal {

enum class CostKind {
  kMaximumLikelihood,  // point-to-line with the target explicit (default)
  kPairwise,           // the paper's eq. 6, for comparison
};
enum class RobustLoss { kNone, kHuber, kCauchy };

// With several PSD placements each placement's centre needs lines from at least this many poses.
constexpr int kMinimumPosesPerPlacement = 3;

struct SolveOptions {
  CostKind cost = CostKind::kMaximumLikelihood;
  // Measurement sigma in mm (miss distance of a line from the hit point, per axis). When unset
  // it is estimated from the residuals (and intervals use Student's t).
  std::optional<double> noise_mm;
  // With readings u,v in the poses: the hit-point model (the line passes through c + R_psd(u,v,0)).
  bool use_readings = true;
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale_sigmas = 3.0;  // where the robust loss starts to bend, in noise sigmas
  int max_iterations = 200;
  // The accuracy the calibration is for: an offset whose one-sigma uncertainty is larger is not
  // determined, and the result is not usable.
  double required_accuracy_deg = 0.01;
  // Gates of the verdict: an offset beyond this is not a zero offset but a wrong model (robot
  // file, laser direction); misses more than this many times the given noise (the square root
  // of chi-square per degree of freedom) mean the stated noise or the model is not the cell's.
  double max_offset_deg = 10.0;
  double max_noise_scale = 5.0;
  // The model's own uncertainty: the robot's link lengths (a, d) and twists (alpha), which the
  // method does not identify, known to these one-sigma tolerances. Their effect on each estimate
  // is a bias no number of poses averages away; it is added to the statistical sigma as a
  // consider covariance (ParameterEstimate::model_sigma). 0: the model is taken as exact.
  double model_length_mm = 0;
  double model_angle_deg = 0;
  // The gravity sag of joints 2 and 3 (several placements, a robot file with a gravity model):
  // identify_compliance makes their compliance unknowns of the solve (docs/maths.md section 8);
  // otherwise the sag is a model error known to this one-sigma tolerance at the largest gravity
  // torque (deg), counted in the consider covariance as the link tolerances are.
  bool identify_compliance = false;
  double model_sag_deg = 0;
  // Deletion diagnostics (maximum-likelihood cost): a pose whose removal lowers the misfit by
  // more than chance allows at this family-wise level is named and left out of the result.
  bool find_gross_errors = true;
  double gross_error_alpha = 0.01;
  // Polled between iterations; returning true abandons the solve (report.message says so).
  std::function<bool()> cancelled;
  // Returns a description of the first problem, or empty when the options are usable.
  std::string validate() const;
};

struct ParameterEstimate {
  std::string name;  // "delta2_deg", "laser_slope_1", ...
  bool identifiable = true;
  std::string reason;      // why not, when not
  double value = 0;        // degrees for offsets, as named otherwise
  double sigma = 0;        // one standard deviation, same unit; the model's part included
  double model_sigma = 0;  // of sigma, the part from the link tolerances (model_length_mm, ...)
  double ci95_low = 0, ci95_high = 0;
};

struct PoseResidual {
  int source_line = 0;
  bool used = true;      // false: left out of the fit (a gross error, or a duplicate)
  int duplicate_of = 0;  // 1-based pose this one repeats exactly, 0 when none
  Eigen::Vector2d miss_mm = Eigen::Vector2d::Zero();  // line's miss of the hit point, 2 axes
  double miss_norm_mm = 0;
  double normalised = 0;  // miss_norm / sigma
  bool outlier = false;   // named by the deletion diagnostics as not fitting the others
  double standoff_mm = 0;
};

// Whether the result may be used as a correction, and if not, why not (each reason a sentence).
struct Verdict {
  bool usable = false;
  std::vector<std::string> reasons;
};

// A pose the result does not rest on: one that does not fit the others (left out), or an exact
// duplicate of an earlier pose (counted once).
struct SuspectPose {
  int pose = 0;  // 1-based position in the given poses
  int source_line = 0;
  std::string reason;
  // Chi-square per degree of freedom of the fit without this pose, in the given noise (or, when
  // the noise is estimated, in the result's noise estimate).
  double chi2_without = 0;
};

struct SolveReport {
  Verdict verdict;
  std::vector<SuspectPose> suspect_poses;
  // 1-based poses worth measuring again: each one named as not fitting, and both poses of a pair
  // the data cannot decide between. A recorder (the daemon) measures them again and solves anew.
  std::vector<int> remeasure;
  bool converged = false;
  std::string message;  // Ceres' summary line, or why it stopped
  CostKind cost = CostKind::kMaximumLikelihood;
  bool used_readings = false;
  int pose_count = 0;  // as given, duplicates and left-out poses included
  int poses_used = 0;  // in the fit
  double required_accuracy_deg = 0;
  double model_length_mm = 0, model_angle_deg = 0;  // the link tolerances counted (SolveOptions)
  double model_sag_deg = 0;  // the sag tolerance counted (several placements, SolveOptions)

  // The 8 of unknownName order; with several placements then the 18 link errors
  // (linkParamName order), each identified or named in not_identifiable with the reason.
  std::vector<ParameterEstimate> parameters;
  struct NotIdentifiable {
    std::string name, reason;
  };
  std::vector<NotIdentifiable> not_identifiable;  // always delta1 and delta6, plus any others
  CalibrationParameters estimate;  // radians inside; target_mm: the first placement's
  Eigen::Vector3d target_sigma_mm = Eigen::Vector3d::Zero();
  // With two or more PSD placements, each placement's centre (empty with one).
  struct PlacementCentre {
    int placement = 1;  // the joint set's number
    int poses = 0;      // poses aimed at it (duplicates included)
    Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
    Eigen::Vector3d target_sigma_mm = Eigen::Vector3d::Zero();
  };
  std::vector<PlacementCentre> placements;
  Eigen::MatrixXd correlation;  // 8 x 8, NaN where not identifiable

  int rank = 0;  // with several placements: the number of identified unknowns (base parameters)
  double condition_number = 0;
  int dof = 0;
  double noise_mm = 0;                 // the sigma behind the reported uncertainties
  bool noise_estimated = false;        // true: from the residuals; false: given
  std::optional<double> chi2_per_dof;  // only when the noise was given, in the given noise
  std::optional<double> chi2_p_value;  // chance of a chi-square this large with the given noise
  // sqrt(chi2/dof) when the poses miss by more than the given noise (then noise_mm is the given
  // noise times this, and the intervals use Student's t), else 1.
  double noise_scale = 1;
  double rms_miss_mm = 0;
  std::vector<PoseResidual> poses;

  int iterations = 0;
  double solve_time_ms = 0;
};

// Throws InputError for fewer than kMinimumPoses poses or a pose outside the robot's joint limits
// (naming the pose and its source line): what every pose set must pass before a solve, and
// before the robot moves for a plan.
void checkPoses(const CellModel& cell, const std::vector<Pose>& poses);

// Throws InputError for fewer than kMinimumPoses distinct poses, joints outside the robot's
// limits, or invalid options; with poses at two or more PSD placements (Pose::placement), also
// for fewer than kMinimumPosesPerPlacement at a placement, or for the pairwise cost or a robust
// loss, which that solve does not offer. Everything else (non-convergence, unidentifiable
// parameters, poses that do not fit) is in the report, and its verdict says whether the result may
// be used.
SolveReport solve(const CellModel& cell, const std::vector<Pose>& poses,
                  const SolveOptions& options = {});

}  // namespace zerocal
