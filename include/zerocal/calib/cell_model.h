// What the solver knows of the cell; the unknowns it identifies are zerocal/results/parameters.h.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "zerocal/calib/pose_count.h"
#include "zerocal/io/joint_set.h"
#include "zerocal/model/laser.h"
#include "zerocal/model/robot.h"
#include "zerocal/results/parameters.h"
#include "zerocal/results/placements.h"

namespace zerocal {

// The noise of a pose's two misses (docs/maths.md section 5). A real arm's noise is each joint's
// repeatability; seen at the detector through the pose's joint Jacobian it is pose-dependent and
// anisotropic (0.021..0.039 mm per pose on the simulated IRB 1600, axis ratio up to 1.6), and
// much of it moves the beam as a change of an offset or the laser's slope does. With
// joint_repeatability_deg set, each pose's misses are weighed by their own covariance
//
//   Sigma_i = s_q^2 J_q,i J_q,i^T + s_psd^2 J_uv,i J_uv,i^T
//
// (J_q: the misses' derivatives by the six joints, J_uv: by the reading), expressed in units of
// referenceMm(): the solve's misses are W_i m_i with W_i = referenceMm() Sigma_i^-1/2, so that
// everything downstream of them (chi-square, covariance, deletion test, the change solve's pairs)
// reads them as misses of that one sigma. Unset: every pose has the solve's noise_mm.
struct MissNoise {
  double joint_repeatability_deg = 0;  // one sigma per joint per move
  double psd_mm = 0;                   // the detector's reading noise per axis
  bool perPose() const { return joint_repeatability_deg > 0; }
  // The sigma the weighed misses are in: what the joints' repeatability moves a point 1 m from
  // the joint axis by, with the detector's noise, a figure of the model alone (not of the poses,
  // so that every subset of a pose set, every solve and the plan's prediction share it).
  double referenceMm() const;
};

struct CellModel {
  Robot robot;
  LaserModel laser;
  // Orientation of the PSD in the base frame: columns are the PSD's u axis, v axis and normal.
  // Used only for poses that carry a PSD reading (the hit-point model).
  Eigen::Matrix3d psd_rotation = Eigen::Matrix3d::Identity();
  // With several PSD placements: the orientation at placement 2, 3, ... (placement_rotations[0]
  // is placement 2's). A placement without an entry has psd_rotation.
  std::vector<Eigen::Matrix3d> placement_rotations;

  // The PSD's orientation at a 1-based placement.
  const Eigen::Matrix3d& psdRotation(int placement) const;
  MissNoise noise;
};

// The matrix that weighs pose's two misses (W_i above) at the parameters `at` (their target the
// pose's placement's); the identity when the noise is not per pose.
Eigen::Matrix2d missWeight(const CellModel& cell, const Pose& pose, const CalibrationParameters& at,
                           bool use_readings);
// The cell with every pose's noise alike: its misses are those at the detector, unweighed (what
// a report shows the technician).
CellModel atDetector(CellModel cell);
// Sigma_i of the pose at `at` (mm^2); noise_mm^2 I when the noise is not per pose.
Eigen::Matrix2d missCovariance(const CellModel& cell, const Pose& pose,
                               const CalibrationParameters& at, bool use_readings, double noise_mm);

// The robot with the link errors added to its DH rows (and kept as its identified errors).
Robot withLinkErrors(const Robot& robot, const Eigen::Matrix<double, kLinkParameterCount, 1>& link);
// The robot as calibrated: the identified link errors and compliance of `params` added to its
// own (a robot file written with them reproduces the identified kinematics).
Robot calibratedRobot(const Robot& robot, const CalibrationParameters& params);

// A laser line in the base frame: point and unit direction.
struct Line {
  Eigen::Vector3d point;
  Eigen::Vector3d direction;
};

// The laser line in the base frame for controller joints q and the given parameters.
Line laserLine(const CellModel& cell, const Joints& q_deg, const CalibrationParameters& params);

// The point closest to a bundle of lines in the least-squares sense:
// c* = (sum P_i)^-1 sum P_i p_i, P_i = I - d_i d_i^T. Needs two non-parallel lines.
Eigen::Vector3d closestPointToLines(const std::vector<Line>& lines);

// The point each pose's line must pass through: c, or c + R_psd (u, v, 0) with a reading, R_psd
// the orientation at the pose's placement.
Eigen::Vector3d hitPointOffset(const CellModel& cell, const Pose& pose, bool use_readings);

}  // namespace zerocal
