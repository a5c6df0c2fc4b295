// The seam between zerocal and the calibration a robot controller keeps: each motor's zero (on an
// ABB IRC5, MOC MOTOR_CALIB cal_offset), read, written, taken by a restart, and the motors'
// angles by which a joint's transmission is measured. The online apply
// (zerocal/apply/online_apply.h) speaks only this; Irc5Client implements it over the RAPID
// module (requests 41, 45, 46, 48), and a connected cell hands it out
// (ConnectedCell::calibration).
#pragma once

#include <array>

namespace zerocal {

class ControllerCalibration {
 public:
  virtual ~ControllerCalibration() = default;
  // The six motors' zeros as configured, radians within one motor turn [0, 2 pi). Throws a
  // LinkError.
  virtual std::array<double, 6> readCalOffsets() = 0;
  // Configures joint (1..6)'s zero, radians in [0, 2 pi); the motion system takes it at the next
  // restart(). Throws a LinkError (of kind refused when the controller does not accept it).
  virtual void writeCalOffset(int joint, double rad) = 0;
  // Restarts the controller so that written values take effect; returns when it answers again
  // (the link reconnected). Throws a LinkError when it does not come back.
  virtual void restart() = 0;
  // The six motors' angles now, radians, as the controller measures them (an IRC5: RAPID
  // ReadMotor). Only differences are meaningful: whether the value stays within one motor turn
  // or counts turns is the controller's, so a caller unwraps the change between two readings.
  // Throws a LinkError (of kind refused when the controller cannot report them).
  virtual std::array<double, 6> readMotorAngles() = 0;
  // Updates joint (1..6)'s revolution counter with the joint at its synchronisation mark. False
  // when this controller cannot do it remotely (an IRC5 over RAPID: a technician does it on the
  // FlexPendant). Throws a LinkError.
  virtual bool updateRevolutionCounter(int joint) {
    (void)joint;
    return false;
  }
};

}  // namespace zerocal
