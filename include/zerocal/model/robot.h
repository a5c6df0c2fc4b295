// A 6R serial arm in standard Denavit-Hartenberg form, as read from a robot YAML file.
//
// Conventions (fixed for the whole project, see docs/maths.md):
//   T_i = Rz(theta_i) * Tz(d_i) * Tx(a_i) * Rx(alpha_i),  theta_i = q_i + theta_offset_i + delta_i
// q_i are controller joint angles (degrees at the interfaces, radians inside the maths); the
// flange (tool0) frame is DH frame 6. Lengths are millimetres.
#pragma once

#include <array>
#include <string>

namespace zerocal {

constexpr int kJointCount = 6;

// Controller joint angles in degrees (the IRC5's CJointT convention).
using Joints = std::array<double, kJointCount>;

struct DhRow {
  double a_mm = 0;
  double alpha_rad = 0;
  double d_mm = 0;
  double theta_offset_rad = 0;
};

struct JointLimit {
  double lower_deg = 0;
  double upper_deg = 0;
};

struct Robot {
  std::string name;
  std::array<DhRow, kJointCount> dh;
  std::array<JointLimit, kJointCount> limits;
  std::array<double, kJointCount> max_speed_deg_s{};
  // Each joint's transmission: the motor angle change per joint angle change, signed (negative:
  // the motor turns backwards when the joint turns forwards). 0: not given in the robot file.
  // It takes an arm-side offset to the motor side, where the controller keeps its calibration.
  std::array<double, kJointCount> transmission{};
  // false: the values above are placeholders to be confirmed on the robot before they are used.
  bool transmission_confirmed = false;

  // True when every joint lies inside its limits shrunk by margin_deg on both sides.
  bool withinLimits(const Joints& q_deg, double margin_deg = 0.0) const;
  // Describes the first joint outside its limits ("joint 3 = 70.000 deg is outside
  // [-245, 65] deg"), or returns an empty string when all are inside.
  std::string limitViolation(const Joints& q_deg, double margin_deg = 0.0) const;
};

// Reads and validates a robot file. Throws ConfigError listing every problem found
// (missing fields, wrong types, lower >= upper limits, non-positive speeds, ...).
Robot loadRobot(const std::string& path);
// The same from YAML text; origin names the source in error messages.
Robot parseRobot(const std::string& yaml_text, const std::string& origin);

}  // namespace zerocal
