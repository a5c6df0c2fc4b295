// A second controller kind for the tests, beside the IRC5: "line", a controller that speaks a
// protocol of its own (one text line a request, one a reply) over TCP, with its own section of
// the configuration (controller.line: host, port, speed, limit margin), its own motion model,
// and its fake server over the vendor-free simulated arm (sim::SimulatedArm). It shows what a
// new controller kind is: a link, its settings and a line in the kinds' list (here a
// registration, as a test adds it at run time).
//
// The protocol: requests are words separated by spaces, a reply is "OK" and its values, or "ERR"
// and a reason.
//   HELLO                      -> OK <type> <serial> <software>
//   PING                       -> OK
//   SPEED <tcp mm/s> <ori deg/s> -> OK
//   JOINTS                     -> OK <6 joint angles, deg>
//   POSE                       -> OK <x y z mm> <qw qx qy qz>
//   MOVEJ <6 joint angles>     -> OK | ERR out_of_limits
//   MOVEL <x y z> <qw qx qy qz> -> OK | ERR out_of_limits | ERR unreachable
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "zerocal/cell/controller_kind.h"
#include "zerocal/sim/simulated_arm.h"

namespace zerocal::testing {

// The line controller's moves: every joint at most at `joint_speed_deg_s`, no ramp, and a fixed
// cost and settling per move. The fake server charges the arm's clock by it, and the kind's
// ControllerMotion orders a plan by it.
struct LineMotion {
  double joint_speed_deg_s = 60.0;
  double overhead_s = 0.2;
  double settle_s = 0.1;
  double motionS(const Joints& from, const Joints& to) const;
  sim::MotionModel model() const;
};

// The fake line controller: a TCP server on loopback over a simulated arm, one client at a time.
class LineServer {
 public:
  explicit LineServer(sim::SimulatedArm& arm);
  ~LineServer();
  LineServer(const LineServer&) = delete;
  LineServer& operator=(const LineServer&) = delete;
  std::uint16_t port() const { return port_; }
  long requests() const { return requests_.load(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::uint16_t port_ = 0;
  std::atomic<long> requests_{0};
  std::thread thread_;
};

// The controller.line section.
class LineSettings final : public ControllerSettings {
 public:
  std::string host = "127.0.0.1";
  std::uint16_t port = 0;
  double speed_tcp_mm_s = 200.0;
  double limit_margin_deg = 1.5;
  LineMotion motion_model;

  std::unique_ptr<ControllerSettings> clone() const override {
    return std::make_unique<LineSettings>(*this);
  }
  void declare(const std::string& prefix, settings::Fields& fields) override;
  void check(const std::string& prefix, bool real_cell, settings::Checker& check) const override;
  ControllerMotion motion() const override;
  std::unique_ptr<ControllerConnection> link(const Robot& robot,
                                             const LinkEndpoint* endpoint) const override;
};

// The kind "line".
ControllerKind lineKind();

}  // namespace zerocal::testing
