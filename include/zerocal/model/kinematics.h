// Forward kinematics of a standard-DH 6R arm, templated on the scalar type so that Ceres Jets
// flow through it (the cost functors differentiate the joint offsets through this code).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "zerocal/model/robot.h"

namespace zerocal {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;

// A rigid transform: x_parent = R * x_child + p (millimetres).
template <typename T>
struct Frame {
  Mat3<T> R = Mat3<T>::Identity();
  Vec3<T> p = Vec3<T>::Zero();

  Vec3<T> apply(const Vec3<T>& x) const { return R * x + p; }
  Frame operator*(const Frame& child) const { return {R * child.R, R * child.p + p}; }
};

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kRadToDeg = 180.0 / kPi;

// One DH link: Rz(theta) Tz(d) Tx(a) Rx(alpha); theta in radians, the row's theta offset added.
template <typename T>
Frame<T> dhLink(const DhRow& row, const T& joint_rad) {
  using std::cos;
  using std::sin;
  const T theta = joint_rad + T(row.theta_offset_rad);
  const T ct = cos(theta), st = sin(theta);
  const double ca = std::cos(row.alpha_rad), sa = std::sin(row.alpha_rad);
  Frame<T> f;
  f.R << ct, -st * ca, st * sa,  //
      st, ct * ca, -ct * sa,     //
      T(0), T(sa), T(ca);
  f.p << T(row.a_mm) * ct, T(row.a_mm) * st, T(row.d_mm);
  return f;
}

// Pose of the flange (DH frame 6) in the base frame. joint_rad[i] is q_i + delta_i in radians
// (controller angle plus joint offset error); the DH theta offsets are added here.
template <typename T>
Frame<T> flangePose(const Robot& robot, const T* joint_rad) {
  Frame<T> f = dhLink(robot.dh[0], joint_rad[0]);
  for (int i = 1; i < kJointCount; ++i) f = f * dhLink(robot.dh[i], joint_rad[i]);
  return f;
}

// Convenience for doubles: controller angles in degrees plus offsets in degrees.
Frame<double> flangePoseDeg(const Robot& robot, const Joints& q_deg,
                            const Joints& delta_deg = Joints{});

}  // namespace zerocal
