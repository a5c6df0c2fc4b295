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

// The point each pose's line must pass through: c, or c + R_psd (u, v, 0) with a reading, R_psd
// the orientation at the pose's placement.
Eigen::Vector3d hitPointOffset(const CellModel& cell, const Pose& pose, bool use_readings);

}  // namespace zerocal
