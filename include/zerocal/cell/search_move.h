// The continuous spot search (ControllerLink::startSpotSearch / searchRun, docs/irc5.md): the
// controller drives the robot without stopping through the waypoints of a spiral on the PSD
// plane and latches the joints where the PSD's light signal rises.
//
// The spiral is the one the point-by-point search walks, made continuous: on the PSD plane the
// Archimedean spiral r = pitch theta / 2 pi around the search's centre, mapped to joints through
// the image Jacobian's pseudo-inverse at the planned pose, q(x, y) = centre + per_u x + per_v y
// (x, y in mm). Joint-space lines between waypoints are what MoveAbsJ follows, so no inverse
// kinematics is needed and no singularity bites. The waypoints lie `pitch / 2` apart along the
// path; a run covers the radii [from, to] of the spiral.
//
// forEachSearchWaypoint is the one definition of the waypoints, used by the client (which checks
// them before sending), the simulated controller (which follows them) and, written out again in
// RAPID, by the module.
#pragma once

#include <algorithm>
#include <cmath>

#include "zerocal/model/robot.h"

namespace zerocal {

struct SpotSearch {
  Joints centre_deg{};  // the joints that put the spot at the spiral's centre (expected)
  Joints per_u_mm{};    // joint change per mm of spot along the PSD's u axis (deg/mm)
  Joints per_v_mm{};    // ... along v
  double pitch_mm = 8;  // between the spiral's turns
};

// One search move: the spiral from radius from_mm to to_mm at speed_mm_s (the controller's TCP
// speed of the joint moves through the waypoints).
struct SearchRun {
  double from_mm = 0;
  double to_mm = 0;
  double speed_mm_s = 100;
};

// Calls visit(q) for each waypoint of `run`, in order, until it returns false.
template <typename Visit>
void forEachSearchWaypoint(const SpotSearch& search, const SearchRun& run, Visit visit) {
  constexpr double kTwoPi = 2 * 3.14159265358979323846;
  const double spacing = search.pitch_mm / 2;
  for (double theta = kTwoPi * run.from_mm / search.pitch_mm;;) {
    const double r = search.pitch_mm * theta / kTwoPi;
    if (r > run.to_mm + 1e-9) return;
    const double x = r * std::cos(theta), y = r * std::sin(theta);
    Joints q;
    for (int i = 0; i < kJointCount; ++i)
      q[i] = search.centre_deg[i] + search.per_u_mm[i] * x + search.per_v_mm[i] * y;
    if (!visit(q)) return;
    theta += spacing / std::max(r, spacing);
  }
}

}  // namespace zerocal
