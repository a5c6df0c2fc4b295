// The unknowns a calibration identifies, as its results name and hold them (docs/maths.md):
// the joint offsets delta2..delta5 (radians inside the maths, degrees in reports), the four laser
// parameters of LaserModel, the target point c (the PSD centre, base frame, mm) as a nuisance
// parameter, and with several PSD placements the arm's link errors and compliance. delta1 and
// delta6 are not identifiable by construction and are held at zero.
#pragma once

#include <Eigen/Core>
#include <string>

#include "zerocal/model/laser.h"
#include "zerocal/model/robot.h"

namespace zerocal {

constexpr int kOffsetCount = 4;                                    // delta2..delta5
constexpr int kIdentifiedCount = kOffsetCount + kLaserParamCount;  // the paper's 8
constexpr int kTargetCount = 3;
constexpr int kUnknownCount = kIdentifiedCount + kTargetCount;  // with the target: 11
// The arm's link errors (kLinkParameterCount, model/robot.h), identified only from several PSD
// placements: the DH a, d (mm) and alpha (rad inside, deg in reports) of each joint, in the order
// a1, d1, alpha1, a2, ...

struct CalibrationParameters {
  Eigen::Vector4d delta_rad = Eigen::Vector4d::Zero();  // joints 2..5
  Eigen::Vector4d laser = Eigen::Vector4d::Zero();      // LaserModel parameters
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  // Link errors added to the robot's DH rows (a, d in mm, alpha in rad; linkParamName order):
  // zero unless identified from several placements.
  Eigen::Matrix<double, kLinkParameterCount, 1> link =
      Eigen::Matrix<double, kLinkParameterCount, 1>::Zero();
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

}  // namespace zerocal
