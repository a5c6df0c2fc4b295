// The PSD or the laser taken off and mounted again between two sessions in the simulated cell: a
// small rigid move of the detector on its base (in the base frame, turned about its centre) or of
// the laser on the flange (in the flange frame, turned about its exit point), so that what a
// check or a restore does when the comparison's assumption "mounted where the reference had it"
// fails can be measured (backend.sim_psd_moved_mm and _turned_deg, backend.sim_laser_moved_mm and
// _turned_deg; docs/simulated-cell.md). Header-only: the daemon's configuration checks it without
// linking the simulator.
#pragma once

#include <array>
#include <cmath>
#include <sstream>
#include <string>

namespace zerocal {

struct Remount {
  std::array<double, 3> moved_mm{};    // added to the position
  std::array<double, 3> turned_deg{};  // roll, pitch, yaw (R = Rz Ry Rx) applied on top

  bool any() const {
    for (int i = 0; i < 3; ++i)
      if (moved_mm[i] != 0 || turned_deg[i] != 0) return true;
    return false;
  }
};

// The largest re-mount taken, per component: a base or a bracket put back by hand is off by
// tenths of a millimetre and degree, not more; beyond this the servo would search for the spot
// as on a new placement, which is not what a re-mount is.
constexpr double kMaxRemountMm = 5.0;
constexpr double kMaxRemountDeg = 2.0;

// "each `what` must be within +-`limit` `unit` (v given)" for the first of `values` that is not
// finite or beyond the limit, empty when none is.
inline std::string firstBeyond(const std::array<double, 3>& values, double limit, const char* what,
                               const char* unit) {
  for (const double v : values)
    if (!std::isfinite(v) || std::abs(v) > limit) {
      std::ostringstream out;
      out << "each " << what << " must be within +-" << limit << " " << unit << " (" << v
          << " given)";
      return out.str();
    }
  return {};
}

// What is wrong with the moves of `remount` (each component within +-kMaxRemountMm), empty when
// nothing.
inline std::string remountMoveProblem(const Remount& remount) {
  return firstBeyond(remount.moved_mm, kMaxRemountMm, "component", "mm");
}

// The same for its turns (+-kMaxRemountDeg).
inline std::string remountTurnProblem(const Remount& remount) {
  return firstBeyond(remount.turned_deg, kMaxRemountDeg, "angle", "deg");
}

}  // namespace zerocal
