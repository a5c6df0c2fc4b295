// What the solver knows of the cell, and the unknowns it identifies.
//
// Unknowns (docs/maths.md): the joint offsets delta2..delta5 (radians inside the maths, degrees
// in reports), the four laser parameters of LaserModel, and the target point c (the PSD centre,
// base frame, mm) as a nuisance parameter. delta1 and delta6 are not identifiable by
// construction and are held at zero.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "zerocal/calib/pose_count.h"
#include "zerocal/io/joint_set.h"
#include "zerocal/model/laser.h"
#include "zerocal/model/robot.h"

namespace zerocal {

constexpr int kOffsetCount = 4;                                    // delta2..delta5
constexpr int kIdentifiedCount = kOffsetCount + kLaserParamCount;  // the paper's 8
constexpr int kTargetCount = 3;
constexpr int kUnknownCount = kIdentifiedCount + kTargetCount;  // with the target: 11
// The arm's link errors, identified only from several PSD placements: the DH a, d (mm) and
// alpha (rad inside, deg in reports) of each joint, in the order a1, d1, alpha1, a2, ...
constexpr int kLinkParamCount = 3 * kJointCount;

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
};

struct CalibrationParameters {
  Eigen::Vector4d delta_rad = Eigen::Vector4d::Zero();  // joints 2..5
  Eigen::Vector4d laser = Eigen::Vector4d::Zero();      // LaserModel parameters
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  // Link errors added to the robot's DH rows (a, d in mm, alpha in rad; linkParamName order):
  // zero unless identified from several placements.
  Eigen::Matrix<double, kLinkParamCount, 1> link =
      Eigen::Matrix<double, kLinkParamCount, 1>::Zero();
  // The compliance of joints 2 and 3 (rad per kN m of gravity torque, added to the robot file's
  // own): zero unless identified from several placements with a gravity model.
  Eigen::Vector2d compliance = Eigen::Vector2d::Zero();

  // All six joint offsets in degrees (delta1 = delta6 = 0).
  Joints offsetsDeg() const;
};

// "delta2_deg" .. "delta5_deg", then the laser names, then "target_x_mm" .. "target_z_mm".
std::string unknownName(int i);

// "da1_mm", "dd1_mm", "dalpha1_deg", "da2_mm", ...: the link error k of CalibrationParameters.
std::string linkParamName(int k);

// "compliance2_deg_per_knm", "compliance3_deg_per_knm": the compliance k of
// CalibrationParameters, in reports in deg per kN m.
std::string complianceParamName(int k);

// The robot with the link errors added to its DH rows (and kept as its identified errors).
Robot withLinkErrors(const Robot& robot, const Eigen::Matrix<double, kLinkParamCount, 1>& link);
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

// The distinct placement numbers of the poses, ascending.
std::vector<int> placementsOf(const std::vector<Pose>& poses);
inline int placementCount(const std::vector<Pose>& poses) {
  return static_cast<int>(placementsOf(poses).size());
}

// The point each pose's line must pass through: c, or c + R_psd (u, v, 0) with a reading, R_psd
// the orientation at the pose's placement.
Eigen::Vector3d hitPointOffset(const CellModel& cell, const Pose& pose, bool use_readings);

}  // namespace zerocal
