// A motor replaced (or an encoder, or a revolution counter lost) in the simulated cell: one
// joint's true zero moved on top of the world's offsets, so that a reference taken before and a
// check or restore after can be shown (backend.sim_zero_change_joint and _deg,
// docs/simulated-cell.md). Header-only: the daemon's configuration checks it without linking the
// simulator.
#pragma once

#include <cmath>
#include <sstream>
#include <string>

namespace zerocal {

struct ZeroChange {
  int joint = 0;   // 2..5; 0: no change
  double deg = 0;  // added to the joint's true offset
};

// The largest change taken (deg): with the world's offsets of up to 1 deg, the servo still finds
// the spot on the PSD from the nominal plan.
constexpr double kMaxZeroChangeDeg = 2.0;

// What is wrong with `change` (joint 2..5 with 0 < |deg| <= kMaxZeroChangeDeg, or no joint and
// no degrees), empty when nothing.
inline std::string zeroChangeProblem(const ZeroChange& change) {
  std::ostringstream what;
  if (change.joint == 0) {
    if (change.deg != 0) what << "a zero change of " << change.deg << " deg needs its joint (2..5)";
  } else if (change.joint < 2 || change.joint > 5) {
    what << "joint " << change.joint
         << ": only the zeros of joints 2..5 are calibrated, so only they can be changed";
  } else if (!std::isfinite(change.deg) || change.deg == 0 ||
             std::abs(change.deg) > kMaxZeroChangeDeg) {
    what << "the change of joint " << change.joint << "'s zero must be non-zero and within +-"
         << kMaxZeroChangeDeg << " deg (" << change.deg << " given)";
  }
  return what.str();
}

}  // namespace zerocal
