// The gravity torques of joints 2 and 3 from a lumped-mass model (docs/maths.md section 8): the
// regressor of the joints' compliance, and the simulated world's gravity sag.
#include "zerocal/model/gravity.h"

#include <cmath>

#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace {

constexpr double kGravity = 9.80665;  // m/s^2
// kg x (m/s^2) x mm -> kN m
constexpr double kToKnm = kGravity * 1e-6;

// Frames 0 (base) .. 6 (flange) of the arm of robot.dh at q_deg.
std::array<Frame<double>, kJointCount + 1> framesAt(const Robot& robot, const Joints& q_deg) {
  std::array<Frame<double>, kJointCount + 1> frame;
  for (int i = 0; i < kJointCount; ++i)
    frame[i + 1] = frame[i] * dhLink(robot.dh[i], q_deg[i] * kDegToRad);
  return frame;
}

Eigen::Vector3d point(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }

// masses[0 .. count) for a range-for.
struct Masses {
  const LumpedMass* first;
  std::size_t count;
  const LumpedMass* begin() const { return first; }
  const LumpedMass* end() const { return first + count; }
};

}  // namespace

std::array<double, kComplianceCount> gravityTorqueKnm(const Robot& robot,
                                                      const std::vector<LumpedMass>& masses,
                                                      const Joints& q_deg) {
  return gravityTorqueKnm(robot, masses.data(), masses.size(), q_deg);
}

std::array<double, kComplianceCount> gravityTorqueBoundKnm(const Robot& robot,
                                                           const std::vector<LumpedMass>& masses) {
  return gravityTorqueBoundKnm(robot, masses.data(), masses.size());
}

std::array<double, kComplianceCount> gravityTorqueKnm(const Robot& robot, const LumpedMass* masses,
                                                      std::size_t count, const Joints& q_deg) {
  std::array<double, kComplianceCount> torque{};
  if (count == 0) return torque;
  const auto frame = framesAt(robot, q_deg);
  const Eigen::Vector3d down(0, 0, -1);
  for (int c = 0; c < kComplianceCount; ++c) {
    const int joint = c + 2;
    // Joint j turns about z of frame j-1, through its origin.
    const Frame<double>& axis = frame[joint - 1];
    for (const LumpedMass& m : Masses{masses, count}) {
      if (m.link < joint) continue;  // not carried by this joint
      const Eigen::Vector3d r = frame[m.link].apply(point(m.at_mm)) - axis.p;
      torque[c] += m.kg * kToKnm * r.cross(down).dot(axis.R.col(2));
    }
  }
  return torque;
}

std::array<double, kComplianceCount> gravityTorqueBoundKnm(const Robot& robot,
                                                           const LumpedMass* masses,
                                                           std::size_t count) {
  // The distances between successive frame origins, and from a link's frame origin before the
  // joint to its mass, are the same at every pose: a mass's distance from joint j's axis is at
  // most the sum of those from the axis' origin out to it.
  const auto frame = framesAt(robot, Joints{});
  std::array<double, kComplianceCount> bound{};
  for (int c = 0; c < kComplianceCount; ++c) {
    const int joint = c + 2;
    for (const LumpedMass& m : Masses{masses, count}) {
      if (m.link < joint) continue;
      double lever = (frame[m.link].apply(point(m.at_mm)) - frame[m.link - 1].p).norm();
      for (int i = joint; i < m.link; ++i) lever += (frame[i].p - frame[i - 1].p).norm();
      bound[c] += m.kg * kToKnm * lever;
    }
  }
  return bound;
}

Joints complianceDeflectionDeg(const Robot& robot, const Joints& q_deg) {
  Joints out{};
  if (!robot.hasCompliance() || !robot.hasGravityModel()) return out;
  const auto torque = gravityTorqueKnm(robot, robot.masses, q_deg);
  for (int c = 0; c < kComplianceCount; ++c)
    out[c + 1] = robot.compliance_deg_per_knm[c] * torque[c];
  return out;
}

}  // namespace zerocal
