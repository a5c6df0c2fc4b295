// The seam between zerocal and a robot controller: the few blocking calls a calibration session
// needs. Irc5Client implements it over TCP; tests use mocks. Every call may throw a LinkError
// subclass (zerocal/irc5/errors.h) and none is retried behind the caller's back.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "zerocal/cell/controller_calibration.h"
#include "zerocal/cell/robot_info.h"
#include "zerocal/cell/search_move.h"
#include "zerocal/model/robot.h"

namespace zerocal {

// A tool pose: position in millimetres, orientation as a unit quaternion (w, x, y, z), both in
// the current work object frame (wobj0 = robot base unless changed).
struct TcpPose {
  std::array<double, 3> xyz_mm{};
  std::array<double, 4> quat_wxyz{1, 0, 0, 0};
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

  // The continuous spot search, where the cell offers it (zerocal/cell/search_move.h): the PSD's
  // light signal wired to one of the controller's digital inputs (docs/irc5.md).
  // startSpotSearch() gives the controller the spiral; false when it offers no search (then
  // searchRun must not be called).
  virtual bool startSpotSearch(const SpotSearch& search) {
    (void)search;
    return false;
  }
  // Drives the robot through one run of the spiral without stopping. Returns the joints (deg)
  // where the signal rose, the robot at rest a little further along; nullopt when it did not
  // rise, the robot at the run's last waypoint. Throws a LinkError of kind kRefused, nothing
  // sent, when a waypoint lies outside the limits less the margin or a step between waypoints
  // exceeds the step limit.
  virtual std::optional<Joints> searchRun(const SearchRun& run) {
    (void)run;
    return std::nullopt;
  }
};

// A controller link with its connection's life: what a connected cell owns. The cell factory
// (zerocal/service/cell_factory.h) makes one per controller.kind; Irc5Client is the IRC5's.
class ControllerConnection : public ControllerLink {
 public:
  // Connects and prepares the controller for calibration moves (tool, speeds, fine points), and
  // checks the robot file against the controller's own limits. Throws a LinkError, or
  // ConfigError when the robot file and the controller disagree.
  virtual void connect() = 0;
  // Closes and connects again, with bounded attempts of its own; throws the last LinkError.
  virtual void reconnect() = 0;
  // Stops the robot between moves (a move in progress ends at its target). Throws a LinkError.
  virtual void stop() = 0;
  virtual bool connected() const noexcept = 0;
  virtual void close() noexcept = 0;
  // The controller's motor calibration over this connection; nullptr when the link offers none.
  virtual ControllerCalibration* calibration() noexcept { return nullptr; }
};

}  // namespace zerocal
