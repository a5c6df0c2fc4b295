#include "zerocal/irc5/motion_time.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace irc5 {

double jointMoveSeconds(const Robot& robot, const Joints& from, const Joints& to, double v_tcp_mm_s,
                        double v_ori_deg_s) {
  double seconds = 0;
  for (int i = 0; i < kJointCount; ++i) {
    double speed = std::min(robot.max_speed_deg_s[i], v_ori_deg_s);
    if (!(speed > 0)) speed = v_ori_deg_s;
    seconds = std::max(seconds, std::abs(to[i] - from[i]) / speed);
  }
  // 16 chords follow a joint-space line closely enough for a deadline (within a few percent of
  // the arc for the largest moves).
  constexpr int kSamples = 16;
  double path_mm = 0;
  Frame<double> previous = flangePoseDeg(robot, from);
  const Frame<double> first = previous;
  for (int k = 1; k <= kSamples; ++k) {
    Joints q;
    for (int i = 0; i < kJointCount; ++i) q[i] = from[i] + (to[i] - from[i]) * k / kSamples;
    const Frame<double> f = flangePoseDeg(robot, q);
    path_mm += (f.p - previous.p).norm();
    previous = f;
  }
  const double turn_deg = Eigen::AngleAxisd(first.R.transpose() * previous.R).angle() * kRadToDeg;
  return std::max({seconds, path_mm / v_tcp_mm_s, turn_deg / v_ori_deg_s});
}

std::string MotionCosts::validate() const {
  if (!(overhead_s >= 0) || !(overhead_s <= 60)) return "overhead_s must be in [0, 60] s";
  if (!(joint_accel_deg_s2 > 0)) return "joint_accel_deg_s2 must be positive";
  if (!(settle_s >= 0) || !(settle_s <= 60)) return "settle_s must be in [0, 60] s";
  return {};
}

double rampedSeconds(double cruise_s, double largest_joint_deg, double accel_deg_s2) {
  if (!(cruise_s > 0) || !(largest_joint_deg > 0)) return std::max(0.0, cruise_s);
  // The joints move in step along the path s = 0..1: cruise speed 1 / cruise_s, acceleration
  // limited by the joint that moves most. Ramping up and down to that speed costs v / a of the
  // time (half of each ramp is travel the cruise would have covered).
  const double v = 1.0 / cruise_s;
  const double a = accel_deg_s2 / largest_joint_deg;
  if (v * v / a <= 1.0) return cruise_s + v / a;
  return 2.0 / std::sqrt(a);  // never reaches the speed: accelerate half way, brake the rest
}

MoveTime jointMoveTime(const Robot& robot, const Joints& from, const Joints& to, double v_tcp_mm_s,
                       double v_ori_deg_s, const MotionCosts& costs) {
  double largest = 0;
  for (int i = 0; i < kJointCount; ++i) largest = std::max(largest, std::abs(to[i] - from[i]));
  MoveTime t;
  t.motion_s = rampedSeconds(jointMoveSeconds(robot, from, to, v_tcp_mm_s, v_ori_deg_s), largest,
                             costs.joint_accel_deg_s2);
  t.overhead_s = costs.overhead_s;
  t.settle_s = costs.settle_s;
  return t;
}

}  // namespace irc5
}  // namespace zerocal
