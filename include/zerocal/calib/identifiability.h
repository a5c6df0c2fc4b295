// What a pose set can and cannot determine, from the SVD of the column-scaled Jacobian.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"

namespace zerocal {

struct Identifiability {
  int rank = 0;                 // numerical rank of the column-scaled Jacobian (of 11)
  double condition_number = 0;  // largest / smallest singular value (infinite when rank < 11)
  Eigen::VectorXd singular_values;
  // Per unknown (kUnknownCount entries, in unknownName order):
  std::vector<bool> identifiable;
  std::vector<std::string> reason;  // why not, in words; empty when identifiable
  // Covariance of the unknowns for unit measurement sigma: the pseudo-inverse of J^T J on the
  // identifiable subspace (multiply by sigma^2). Rows/columns of unidentifiable unknowns are NaN.
  Eigen::MatrixXd unit_covariance;
};

// jacobian: whitened residual Jacobian (2N x 11) at the parameters; poses and parameters give
// the words of the reasons (joint-1 span, stand-off spread, ...). sigma_mm converts the unit
// covariance into standard deviations; an offset whose standard deviation exceeds
// required_accuracy_deg counts as not determined (not identifiable, with the figure in the reason,
// called `bound_name`: the solve's is the required accuracy, a plan's prediction the largest
// sigma at which an offset's value means anything).
Identifiability analyseIdentifiability(const Eigen::MatrixXd& jacobian, const CellModel& cell,
                                       const std::vector<Pose>& poses,
                                       const CalibrationParameters& params, double sigma_mm,
                                       double required_accuracy_deg,
                                       const std::string& bound_name = "the required accuracy");

// Why delta1 and delta6 can never be identified by this method.
std::string delta1Reason();
std::string delta6Reason();

// Whitened point-to-line Jacobian, 2N x 11 (columns: delta2..5 in rad, laser, target in mm).
Eigen::MatrixXd pointToLineJacobian(const CellModel& cell, const std::vector<Pose>& poses,
                                    const CalibrationParameters& params, double sigma_mm,
                                    bool use_readings);

// Stand-off of each pose: distance along the laser from its point p_E to the target, mm.
std::vector<double> standoffs(const CellModel& cell, const std::vector<Pose>& poses,
                              const CalibrationParameters& params);

// ---- Several PSD placements (docs/maths.md section 8) ----
//
// The unknowns of a session with P placements: delta2..delta5, the laser's four, the 18 link
// errors (linkParamName order), the compliance of joints 2 and 3 when the robot has a gravity
// model, then the centre (3) of each placement in ascending placement number.
struct PlacementLayout {
  std::vector<int> placements;  // the placement numbers, ascending
  int compliance = 0;           // kComplianceCount with a gravity model, else 0

  // With the compliance unknowns when `identify_compliance` and the robot has a gravity model.
  PlacementLayout(const std::vector<Pose>& poses, const Robot& robot, bool identify_compliance)
      : placements(placementsOf(poses)),
        compliance(identify_compliance && robot.hasGravityModel() ? kComplianceCount : 0) {}
  int count() const { return static_cast<int>(placements.size()); }
  static constexpr int firstLink() { return kIdentifiedCount; }
  static constexpr int firstCompliance() { return kIdentifiedCount + kLinkParameterCount; }
  int firstTarget() const { return firstCompliance() + compliance; }
  int unknownCount() const { return firstTarget() + kTargetCount * count(); }
  bool isLink(int k) const { return k >= firstLink() && k < firstCompliance(); }
  bool isCompliance(int k) const { return k >= firstCompliance() && k < firstTarget(); }
  // 0-based position of a placement number; throws std::out_of_range for an unknown one.
  int slot(int placement) const;
  // unknownName, linkParamName, complianceParamName, or "target2_x_mm" (placement 2's centre).
  std::string name(int k) const;
  // In words, for reasons: "delta3", "the laser line", "da2", "the compliance of joint 2",
  // "the placement-2 centre".
  std::string readable(int k) const;
};

// Whitened point-to-line Jacobian with the link errors, 2N x layout.unknownCount() (columns:
// delta2..5 in rad, laser, link errors in mm and rad, the compliance in rad per kN m when the
// layout has it, the centres in mm), at `params` (its target_mm unused) with targets[slot] the
// centre of each placement. With `residuals`, also the whitened misses (2N).
Eigen::MatrixXd placementJacobian(const CellModel& cell, const std::vector<Pose>& poses,
                                  const PlacementLayout& layout,
                                  const CalibrationParameters& params,
                                  const std::vector<Eigen::Vector3d>& targets, double sigma_mm,
                                  bool use_readings, Eigen::VectorXd* residuals = nullptr);

// The base parameters, as FIGAROH finds them, from the Jacobian of poses whose lines pass
// exactly through their centres (where the lines miss, a change that keeps an exact fit exact,
// the arm's scale or a turn about the beam, still moves the misses and would look identifiable):
// the columns of the column-scaled Jacobian are taken
// in order of preference (the offsets, the laser, the centres, the compliance, then the link
// errors joint by joint) and an unknown is kept when its column adds a direction to those kept
// before it (the diagonal of R in a QR decomposition without pivoting, relative to the column,
// above 1e-6). An unknown whose column is zero has "no effect on the measurements"; one whose
// column is a combination of kept ones is "not identifiable: combined with ..." the kept unknowns
// that combination leans on (R1^-1 R2, FIGAROH's regrouping). Such unknowns are held at their
// nominal value; the kept ones form a full-rank problem.
struct BaseParameters {
  std::vector<bool> identified;     // per unknown, layout order
  std::vector<std::string> reason;  // why not, empty when identified
  int count = 0;                    // identified unknowns
};
BaseParameters analyseBaseParameters(const Eigen::MatrixXd& jacobian,
                                     const PlacementLayout& layout);

// The unit-sigma covariance (layout order, NaN rows and columns for unknowns not identified) of
// the identified unknowns, the pseudo-inverse of J_b^T J_b with J_b the Jacobian's identified
// columns, and the condition number of J_b column-scaled.
Eigen::MatrixXd baseCovariance(const Eigen::MatrixXd& jacobian, const BaseParameters& base,
                               double* condition_number = nullptr);

// The point each placement's nominal lines pass closest to (through the hit points), per slot.
std::vector<Eigen::Vector3d> placementTargets(const CellModel& cell, const std::vector<Pose>& poses,
                                              const PlacementLayout& layout,
                                              const CalibrationParameters& params,
                                              bool use_readings);

}  // namespace zerocal
