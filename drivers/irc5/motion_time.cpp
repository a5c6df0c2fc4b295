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

}  // namespace irc5
}  // namespace zerocal
