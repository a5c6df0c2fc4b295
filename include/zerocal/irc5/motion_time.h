// How long a move takes on an IRC5, for deadlines (client) and the simulated clock (simulator).
//
// jointMoveSeconds: the cruise time of a MoveAbsJ at a given speeddata, limited three ways: each
// joint's own maximum speed (capped by v_ori, as the controller never turns a joint faster than
// the orientation speed allows), the TCP path speed v_tcp, and the tool's reorientation speed
// v_ori. The TCP path of a joint move is curved; it is measured by sampling the joint-interpolated
// path.
//
// moveTime: what a real controller charges on top (docs/simulated-cell.md gives the evidence for
// each default): a fixed cost per move (the request and reply, RAPID starting the instruction, the
// motion planner queueing the path before the servos follow it), a trapezoidal speed profile (the
// joints accelerate and brake, synchronised so that they all arrive together), and the settling
// at the fine point before WaitRob \InPos lets the RAPID server reply.
#pragma once

#include <string>

#include "zerocal/model/robot.h"

namespace zerocal {
namespace irc5 {

// Seconds for a joint move from `from` to `to` (deg) with tool0, at v_tcp_mm_s and v_ori_deg_s
// (both > 0), at constant speed: no acceleration, no per-move costs.
double jointMoveSeconds(const Robot& robot, const Joints& from, const Joints& to, double v_tcp_mm_s,
                        double v_ori_deg_s);

// The costs of a move beyond its distance over its speed.
struct MotionCosts {
  // Fixed per move (s): request and reply, instruction start-up, the planner's path queue.
  double overhead_s = 0.3;
  // Every joint's acceleration and deceleration (deg/s^2); the slowest joint sets the profile.
  double joint_accel_deg_s2 = 1000.0;
  // From the end of the interpolated path until the axes are in position at the fine point (s).
  double settle_s = 0.1;

  // Empty when usable, else the first problem.
  std::string validate() const;
};

// One move's duration, by where the time goes.
struct MoveTime {
  double motion_s = 0;    // accelerating, cruising, braking
  double overhead_s = 0;  // the fixed cost
  double settle_s = 0;    // in position at the fine point
  double total() const { return motion_s + overhead_s + settle_s; }
};

// Duration of a path that takes `cruise_s` at constant speed when the joint that moves most
// moves `largest_joint_deg`, with a trapezoidal profile of joint acceleration `accel_deg_s2`
// (a triangle when the move is too short to reach the speed).
double rampedSeconds(double cruise_s, double largest_joint_deg, double accel_deg_s2);

// A joint move with every cost: jointMoveSeconds ramped, plus the overhead and the settling.
MoveTime jointMoveTime(const Robot& robot, const Joints& from, const Joints& to, double v_tcp_mm_s,
                       double v_ori_deg_s, const MotionCosts& costs);

}  // namespace irc5
}  // namespace zerocal
