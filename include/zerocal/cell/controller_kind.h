// A kind of controller, as the rest of zerocal sees it: the section of the configuration it owns
// (controller.<kind>: its keys, its checks), its motion model, its link, and its notes for the
// report. The daemon's configuration holds only the kind's name (controller.kind), the robot file
// and the servo's step ceiling; everything about talking to one make of controller sits in that
// make's folder (drivers/irc5: ABB's IRC5), and one line of the kinds' list (zerocal/cell/
// kinds.h) names it.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "zerocal/cell/controller_link.h"
#include "zerocal/model/robot.h"
#include "zerocal/settings/settings.h"

namespace zerocal {

// What a controller's moves cost and what it keeps clear of: what the planner, the servo and the
// apply need to know of a controller without knowing which it is.
struct ControllerMotion {
  // Seconds of motion (accelerating, cruising, braking) of a joint move at the configured speeds,
  // without the fixed costs that every move pays alike; the planner orders poses by it.
  std::function<double(const Robot& robot, const Joints& from, const Joints& to)> travel_s;
  // From the end of a move's path until the axes are in position at a fine point (s).
  double settle_s = 0;
  // Every move stays this far inside the joint limits (deg).
  double limit_margin_deg = 0;
  // The linear speed of the servo's sweeps and searches cannot exceed this (mm/s).
  double linear_speed_mm_s = 0;
  // The longest wait for the controller to come back after a restart (the online apply).
  std::chrono::milliseconds restart_timeout{0};
};

// Where a link should connect instead of the address in its section: the simulated cell's
// controller, which listens on loopback at a port of its own.
struct LinkEndpoint {
  std::string host;
  std::uint16_t port = 0;
  // The first reconnection back-off; a simulated controller is back at once.
  std::chrono::milliseconds backoff_initial{0};
};

// One controller kind's section of the configuration and what it makes.
class ControllerSettings : public settings::KindSection {
 public:
  virtual std::unique_ptr<ControllerSettings> clone() const = 0;
  virtual ControllerMotion motion() const = 0;
  // The link, not connected, driving `robot` (the model of controller.robot): to the controller
  // the section names, or to `endpoint` when given. Throws ConfigError for options the link
  // refuses.
  virtual std::unique_ptr<ControllerConnection> link(const Robot& robot,
                                                     const LinkEndpoint* endpoint) const = 0;
};

// A kind: the word of controller.kind (and its section's name), and its section's defaults.
struct ControllerKind {
  std::string name;
  // What the controller is, for messages and docs ("ABB IRC5 through zerocal's RAPID server").
  std::string description;
  std::function<std::unique_ptr<ControllerSettings>()> defaults;
};

}  // namespace zerocal
