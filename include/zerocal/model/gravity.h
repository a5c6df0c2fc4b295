// The gravity torques of robot.h over masses held in any contiguous storage: for callers that
// must not allocate (the simulated world's beam, evaluated in the servo's cycle). A header of its
// own so that adding these did not touch robot.h, which every module includes.
#pragma once

#include <array>
#include <cstddef>

#include "zerocal/model/robot.h"

namespace zerocal {

// gravityTorqueKnm(robot, masses, q_deg) over masses[0 .. count).
std::array<double, kComplianceCount> gravityTorqueKnm(const Robot& robot, const LumpedMass* masses,
                                                      std::size_t count, const Joints& q_deg);
// gravityTorqueBoundKnm(robot, masses) over masses[0 .. count).
std::array<double, kComplianceCount> gravityTorqueBoundKnm(const Robot& robot,
                                                           const LumpedMass* masses,
                                                           std::size_t count);

}  // namespace zerocal
