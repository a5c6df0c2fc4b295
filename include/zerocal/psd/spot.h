// The laser spot on the PSD, one type from the driver to the report: the simulated beam's hit, the
// mapped reading, the servo's path, the journal's pose record, the joint set and the report all
// hold a PsdSpot rather than a u and a v of their own.
//
// Frame: the PSD frame, origin at the detector's centre, u along its x axis and v along its y
// axis (CellModel::psd_rotation's first two columns, zerocal/calib/cell_model.h). Millimetres.
#pragma once

#include <cmath>

namespace zerocal {

// A point on the detector, or a pair of per-axis quantities in its frame (a reading's standard
// errors). Millimetres.
struct PsdSpot {
  double u_mm = 0, v_mm = 0;

  // Distance from the detector's centre.
  double norm() const noexcept { return std::hypot(u_mm, v_mm); }
  bool finite() const noexcept { return std::isfinite(u_mm) && std::isfinite(v_mm); }

  // Exact: two readings are the same measurement only when every bit agrees.
  friend bool operator==(const PsdSpot& a, const PsdSpot& b) noexcept {
    return a.u_mm == b.u_mm && a.v_mm == b.v_mm;
  }
  friend bool operator!=(const PsdSpot& a, const PsdSpot& b) noexcept { return !(a == b); }
};

// One point of the spot's path on the detector: where it was, t_s seconds of cell time after the
// servo's start. The servo keeps them (zerocal/servo/servo.h), the journal writes them as
// [t_s, u_mm, v_mm] (zerocal/store/journal.h), the report draws them.
struct SpotPathPoint {
  double t_s = 0;
  PsdSpot spot;

  friend bool operator==(const SpotPathPoint& a, const SpotPathPoint& b) noexcept {
    return a.t_s == b.t_s && a.spot == b.spot;
  }
  friend bool operator!=(const SpotPathPoint& a, const SpotPathPoint& b) noexcept {
    return !(a == b);
  }
};

// One PSD reading in the PSD frame (origin at the detector centre), millimetres: what a board's
// readout gives a session (zerocal/cell/psd_reader.h) and the map makes of averaged voltages.
struct PsdReading {
  PsdSpot spot;
  PsdSpot se;  // standard errors of the averaged reading, per axis
  double sum_v = 0;
  // SUM above the detector's threshold: some light is on the detector.
  bool spot_present = false;
  // Present and inside the zone the map was fitted on. When false but present, u and v are only
  // a coarse estimate (saturating voltages over the centre slope): right in sign, too small.
  bool in_valid_zone = false;
  double time_s = 0;  // cell clock at the end of the reading
};

}  // namespace zerocal
