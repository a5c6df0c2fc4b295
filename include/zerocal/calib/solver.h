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
  double outlier_threshold = 3.5;  // |normalised residual| above which a pose is flagged
  // Polled between iterations; returning true abandons the solve (report.message says so).
  std::function<bool()> cancelled;
  // Returns a description of the first problem, or empty when the options are usable.
  std::string validate() const;
};

struct ParameterEstimate {
  std::string name;  // "delta2_deg", "laser_slope_1", ...
  bool identifiable = true;
  std::string reason;  // why not, when not
  double value = 0;    // degrees for offsets, as named otherwise
  double sigma = 0;    // one standard deviation, same unit
  double ci95_low = 0, ci95_high = 0;
};

struct PoseResidual {
  int source_line = 0;
  Eigen::Vector2d miss_mm = Eigen::Vector2d::Zero();  // line's miss of the hit point, 2 axes
  double miss_norm_mm = 0;
  double normalised = 0;  // miss_norm / sigma
  bool outlier = false;
  double standoff_mm = 0;
};

struct SolveReport {
  bool converged = false;
  std::string message;  // Ceres' summary line, or why it stopped
  CostKind cost = CostKind::kMaximumLikelihood;
  bool used_readings = false;
  int pose_count = 0;

  std::vector<ParameterEstimate> parameters;  // the 8 identified, in unknownName order
  struct NotIdentifiable {
    std::string name, reason;
  };
  std::vector<NotIdentifiable> not_identifiable;  // always delta1 and delta6, plus any others
  CalibrationParameters estimate;                 // radians inside
  Eigen::Vector3d target_sigma_mm = Eigen::Vector3d::Zero();
  Eigen::MatrixXd correlation;  // 8 x 8, NaN where not identifiable

  int rank = 0;
  double condition_number = 0;
  int dof = 0;
  double noise_mm = 0;                 // the sigma behind the reported uncertainties
  bool noise_estimated = false;        // true: from the residuals; false: given
  std::optional<double> chi2_per_dof;  // only when the noise was given
  double rms_miss_mm = 0;
  std::vector<PoseResidual> poses;

  int iterations = 0;
  double solve_time_ms = 0;
};

// Throws InputError for fewer than kMinimumPoses poses or a pose outside the robot's joint limits
// (naming the pose and its source line): what every pose set must pass before a solve, and
// before the robot moves for a plan.
void checkPoses(const CellModel& cell, const std::vector<Pose>& poses);

// Throws InputError for fewer than kMinimumPoses poses, joints outside the robot's limits, or
// invalid options. Everything else (non-convergence, unidentifiable parameters) is in the report.
SolveReport solve(const CellModel& cell, const std::vector<Pose>& poses,
                  const SolveOptions& options = {});

}  // namespace zerocal
