// The seam between zerocal and a robot controller: the few blocking calls a calibration session
// needs. Irc5Client implements it over TCP; tests use mocks. Every call may throw a LinkError
// subclass (zerocal/irc5/errors.h) and none is retried behind the caller's back.
#pragma once

#include <array>
#include <string>

#include "zerocal/model/robot.h"

namespace zerocal {

// A tool pose: position in millimetres, orientation as a unit quaternion (w, x, y, z), both in
// the current work object frame (wobj0 = robot base unless changed).
struct TcpPose {
  std::array<double, 3> xyz_mm{};
  std::array<double, 4> quat_wxyz{1, 0, 0, 0};
};

// Identification reported by the controller (code 98).
struct RobotInfo {
  std::string serial;
  std::string software_version;
  std::string robot_type;
};

// What every move costs a controller beyond its motion (s): the fixed cost of a move (request,
// reply, the motion planner's start) and the settling at a fine point. Known for the simulated
// controller (its model); on a real one only measured. The result's pose breakdown shows it.
struct MoveOverhead {
  double fixed_s = 0;
  double settle_s = 0;
};

class ControllerLink {
 public:
  virtual ~ControllerLink() = default;

  // Round trip with no effect; a liveness check.
  virtual void ping() = 0;
  virtual RobotInfo robotInfo() = 0;
  // Joint angles as the controller believes them, degrees (CJointT convention).
  virtual Joints readJoints() = 0;
  // Absolute joint move (MoveAbsJ, fine point); returns when the robot has settled at the target.
  // Throws RequestRefusedError without moving when the target is outside the limits.
  virtual void moveJoints(const Joints& target_deg) = 0;
  // Tool pose in the work object frame.
  virtual TcpPose readPose() = 0;
  // Linear tool move (MoveL, fine point); returns when settled.
  virtual void moveLinear(const TcpPose& target) = 0;
};

}  // namespace zerocal
