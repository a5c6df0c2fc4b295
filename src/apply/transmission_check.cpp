#include "zerocal/apply/transmission_check.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "zerocal/error.h"

namespace zerocal::apply {

namespace {

constexpr double kPiValue = 3.14159265358979323846;
constexpr double kRadPerDeg = kPiValue / 180.0;
// The joints read back after the move home: the controller's 5 decimals and its float32.
constexpr double kBackDeg = 1e-4;

}  // namespace

TransmissionMeasurement measureTransmission(ControllerLink& link,
                                            ControllerCalibration& calibration, const Robot& robot,
                                            int joint, const TransmissionCheckOptions& options) {
  if (joint < 1 || joint > kJointCount) throw Error("no joint " + std::to_string(joint));
  const int i = joint - 1;
  const std::string name = "joint " + std::to_string(joint);
  TransmissionMeasurement m;
  m.joint = joint;
  m.configured = robot.transmission[i];
  if (m.configured == 0)
    throw Error(name + ": the robot file gives no transmission to compare the measurement with");
  if (!(options.step_deg > 0) || !(options.tolerance > 0))
    throw Error("transmission check: step_deg and tolerance must be positive");

  const Joints start = link.readJoints();
  const JointLimit& limit = robot.limits[i];
  double step = std::min(options.step_deg, 90.0 / std::abs(m.configured));
  if (start[i] > 0.5 * (limit.lower_deg + limit.upper_deg)) step = -step;
  Joints target = start;
  target[i] += step;
  const std::array<double, 6> motor_before = calibration.readMotorAngles();
  link.moveJoints(target);  // checked by the link against the limits less its margin
  Joints reached;
  std::array<double, 6> motor_after;
  try {
    reached = link.readJoints();
    motor_after = calibration.readMotorAngles();
  } catch (...) {
    try {
      link.moveJoints(start);
    } catch (...) {
      // The first error is the one to report; the next request finds the link as it is.
    }
    throw;
  }
  link.moveJoints(start);
  const Joints back = link.readJoints();
  for (int k = 0; k < kJointCount; ++k)
    if (std::abs(back[k] - start[k]) > kBackDeg) {
      throw Error(fmt::format(FMT_STRING("{}: after the transmission check joint {} reads {:.5f} "
                                         "deg, not the {:.5f} deg it started from"),
                              name, k + 1, back[k], start[k]));
    }

  m.joint_step_deg = reached[i] - start[i];
  if (std::abs(m.joint_step_deg) < 0.5 * std::abs(step))
    throw Error(name + ": the joint did not move for the transmission check (" +
                std::to_string(m.joint_step_deg) + " deg of " + std::to_string(step) + ")");
  double change = motor_after[i] - motor_before[i];
  change -= 2 * kPiValue * std::round(change / (2 * kPiValue));
  m.motor_change_rad = change;
  m.measured = change / (m.joint_step_deg * kRadPerDeg);
  const bool same_sign = (m.measured > 0) == (m.configured > 0);
  const double relative = m.measured / m.configured - 1;
  m.agrees = same_sign && std::abs(relative) <= options.tolerance;
  if (m.agrees)
    m.message = fmt::format(FMT_STRING("{}: transmission {:+.2f} measured ({:+.4f} rad motor over "
                                       "{:+.4f} deg), the robot file's {:+g} agrees"),
                            name, m.measured, change, m.joint_step_deg, m.configured);
  else if (!same_sign)
    m.message = fmt::format(FMT_STRING("{}: the robot file's transmission is {:+g}, the cell "
                                       "measured {:+.2f} ({:+.4f} rad motor over {:+.4f} deg): "
                                       "the sign is wrong"),
                            name, m.configured, m.measured, change, m.joint_step_deg);
  else
    m.message = fmt::format(FMT_STRING("{}: the robot file's transmission is {:+g}, the cell "
                                       "measured {:+.2f} ({:+.4f} rad motor over {:+.4f} deg): "
                                       "{:.1f}% apart, beyond {:.1f}%"),
                            name, m.configured, m.measured, change, m.joint_step_deg,
                            100 * relative, 100 * options.tolerance);
  return m;
}

}  // namespace zerocal::apply
