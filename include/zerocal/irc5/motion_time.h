// How long a MoveAbsJ takes at a given speeddata, for deadlines (client) and the simulated clock
// (simulator). A joint move is limited three ways: each joint's own maximum speed (capped by
// v_ori, as the controller never turns a joint faster than the orientation speed allows), the
// TCP path speed v_tcp, and the tool's reorientation speed v_ori. The TCP path of a joint move is
// curved; it is measured by sampling the joint-interpolated path.
#pragma once

#include "zerocal/model/robot.h"

namespace zerocal {
namespace irc5 {

// Seconds for a joint move from `from` to `to` (deg) with tool0, at v_tcp_mm_s and v_ori_deg_s
// (both > 0). Ignores acceleration: callers add a margin.
double jointMoveSeconds(const Robot& robot, const Joints& from, const Joints& to, double v_tcp_mm_s,
                        double v_ori_deg_s);

}  // namespace irc5
}  // namespace zerocal
