// Identification of delta2..delta5 and the laser line from recorded poses (Ceres), with the
// uncertainty and identifiability an operator needs to judge the result.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/results/solve_report.h"

namespace zerocal {

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
  // The model's own uncertainty (the robot file's model_tolerance, Robot::tolerance): the link
  // lengths (a, d) and twists (alpha), which the method does not identify, known to its
  // one-sigma tolerances or, for a calibrated model, its covariance. Their effect on each estimate
  // is a bias no number of poses averages away; it is added to the statistical sigma as a
  // consider covariance (ParameterEstimate::model_sigma). Zero: the model is taken as exact.
  // The gravity sag of joints 2 and 3 (several placements, a robot file with a gravity model):
  // identify_compliance makes their compliance unknowns of the solve (docs/maths.md section 8);
  // otherwise the sag is a model error known to model.sag_deg at the largest gravity torque,
  // counted in the consider covariance as the link tolerances are.
  ModelTolerances model;
  bool identify_compliance = false;
  // Deletion diagnostics (maximum-likelihood cost): a pose whose removal lowers the misfit by
  // more than chance allows at this family-wise level is named and left out of the result.
  bool find_gross_errors = true;
  double gross_error_alpha = 0.01;
  // Polled between iterations; returning true abandons the solve (report.message says so).
  std::function<bool()> cancelled;
  // Returns a description of the first problem, or empty when the options are usable.
  std::string validate() const;
};

// The options a solve on this cell runs with: with the noise per pose (cell.noise), noise_mm is
// the model's reference sigma, in which the weighed misses are (given, not estimated).
SolveOptions withCellNoise(const CellModel& cell, SolveOptions options);

// Throws InputError for fewer than kMinimumPoses poses or a pose outside the robot's joint limits
// (naming the pose and its source line): what every pose set must pass before a solve, and
// before the robot moves for a plan.
void checkPoses(const CellModel& cell, const std::vector<Pose>& poses);
// Throws InputError for a pose outside the robot's joint limits, naming the pose and its line.
void checkJointLimits(const CellModel& cell, const std::vector<Pose>& poses);

// Throws InputError for fewer than kMinimumPoses distinct poses, joints outside the robot's
// limits, or invalid options; with poses at two or more PSD placements (Pose::placement), also
// for fewer than kMinimumPosesPerPlacement at a placement, or for the pairwise cost or a robust
// loss, which that solve does not offer. Everything else (non-convergence, unidentifiable
// parameters, poses that do not fit) is in the report, and its verdict says whether the result may
// be used.
SolveReport solve(const CellModel& cell, const std::vector<Pose>& poses,
                  const SolveOptions& options = {});

// The robot as a several-placement solve calibrated it: calibratedRobot of its estimate, the
// model's tolerance then the covariance of the identified link errors (report.link_covariance),
// so that later solves with it count what the calibration left, not the nominal tolerances.
Robot calibratedRobot(const Robot& robot, const SolveReport& report);

}  // namespace zerocal
