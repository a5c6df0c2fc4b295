// A joint's transmission measured on the cell (docs/apply.md, "The transmission measured"): a
// small known joint move, the motor's angle read before and after, the ratio and its sign as
// d(motor) / d(joint). The online apply measures joints 2..5 before it writes anything and
// refuses when the robot file's transmissions disagree with the measurement.
#pragma once

#include <string>

#include "zerocal/cell/controller_calibration.h"
#include "zerocal/cell/controller_link.h"
#include "zerocal/model/robot.h"

namespace zerocal::apply {

struct TransmissionCheckOptions {
  // The joint step (deg), made towards the middle of the joint's range. It is cut so that the
  // motor turns at most a quarter turn at the configured ratio: the change between two readings
  // is unwrapped to (-pi, pi], which stays unambiguous while the true ratio is less than twice
  // the configured one (a larger error aliases, and is refused all the same).
  double step_deg = 0.5;
  // Agreement: the same sign, and |measured / configured - 1| within this.
  double tolerance = 0.02;
};

struct TransmissionMeasurement {
  int joint = 0;                // 1..6
  double configured = 0;        // the robot file's k: motor angle per joint angle, signed
  double measured = 0;          // d(motor) / d(joint), signed
  double joint_step_deg = 0;    // the step as the controller read it back, signed
  double motor_change_rad = 0;  // the motor's change over it, unwrapped
  bool agrees = false;
  std::string message;  // the verdict, naming the joint, the configured and the measured ratio
};

// Reads the joints and the motor angles, moves `joint` (1..6) by the step, reads both again and
// moves back to where it was. Throws Error for a joint the robot file gives no transmission or
// one that did not move, or when the robot is not back where it was (to 1e-4 deg); a LinkError
// from the link: RequestRefusedError (nothing moved) when the step leaves the joint limits less
// the link's margin. When a reading fails after the step, the robot is moved back before the
// error is thrown.
TransmissionMeasurement measureTransmission(ControllerLink& link,
                                            ControllerCalibration& calibration, const Robot& robot,
                                            int joint,
                                            const TransmissionCheckOptions& options = {});

}  // namespace zerocal::apply
