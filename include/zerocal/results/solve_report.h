// A solve's result as result.json and `--json` hold it (docs/results.md): the estimates with
// their uncertainty, the verdict, the poses the result does not rest on, and their JSON. Plain
// values: the solver (zerocal/calib/solver.h) fills them, the daemon, the report and the
// technician's client read them.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/results/parameters.h"

namespace zerocal {

enum class CostKind {
  kMaximumLikelihood,  // point-to-line with the target explicit (default)
  kPairwise,           // the paper's eq. 6, for comparison
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
  bool model_calibrated = false;  // a calibrated model's link covariance counted instead
  // Several placements: the covariance of the calibrated model's link errors (kLinkParameterCount
  // square, mm and rad; Robot::tolerance.link_covariance of calibratedRobot), empty otherwise.
  Eigen::MatrixXd link_covariance;
  // The sag tolerances of joints 2 and 3 counted (SolveOptions; 0: not counted).
  SagTolerances model_sag_deg{};
  // Their means (ModelTolerances::sag_mean_deg; 0 and 0: counted as independent).
  SagTolerances model_sag_mean_deg{};

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
  double noise_mm = 0;  // the sigma behind the reported uncertainties
  // With a per-pose noise model (zerocal/calib/cell_model.h MissNoise): the joints'
  // repeatability (deg) behind it, and noise_mm is the model's reference sigma, in which each
  // pose's weighed misses are; 0: noise_mm is every pose's.
  double joint_repeatability_deg = 0;
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

// The verdict object of a result: {usable, reasons}.
nlohmann::json toJson(const Verdict& verdict);

nlohmann::json toJson(const SolveReport& report);
// The inverse of toJson: toJson(solveReportFromJson(j)) == j. Of the estimate, only the target,
// the offsets and the laser parameters are in the JSON; the rest stays at its default. Throws
// InputError naming `where` and the member that is missing or of the wrong type.
SolveReport solveReportFromJson(const nlohmann::json& json, const std::string& where);

std::string costName(CostKind cost);
// How a solve modelled the readings ("hit-point", "point-to-line") and where its noise came from
// ("given", "estimated from the residuals"): result.json's "model" and "noise_source".
std::string modelName(const SolveReport& report);
std::string noiseSourceName(const SolveReport& report);
// Where the sigma in force came from, for people: "estimated from the residuals", "given 0.0200
// mm, scaled up by sqrt(chi2/dof) = 8.27: the poses miss by more than it", the per-pose model's
// reference, or "given".
std::string noiseText(const SolveReport& report);

}  // namespace zerocal
