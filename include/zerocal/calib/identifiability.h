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
// required_accuracy_deg counts as not determined (not identifiable, with the figure in the reason).
Identifiability analyseIdentifiability(const Eigen::MatrixXd& jacobian, const CellModel& cell,
                                       const std::vector<Pose>& poses,
                                       const CalibrationParameters& params, double sigma_mm,
                                       double required_accuracy_deg);

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

}  // namespace zerocal
