// From an identified arm-side joint offset to the value an ABB IRC5 keeps: MOC type MOTOR_CALIB,
// attribute cal_offset, the motor's resolver angle at the joint's calibration position, in
// radians within one motor turn [0, 2 pi) (every public controller backup we read holds values
// in that range; docs/apply.md).
//
// The model, per joint (k = the signed transmission, motor angle per joint angle; phi = the
// motor angle the controller measures, revolution counter and resolver together):
//
//   controller's joint angle   q     = (phi - cal_offset) / k
//   true joint angle           theta = q + delta                  (docs/results.md)
//
// so delta is removed by moving the motor-side zero by -k x delta:
//
//   cal_offset_new = wrap(cal_offset_old - k x delta),   wrap(x) = x - 2 pi floor(x / 2 pi)
//
// The sign convention of ABB's motor angle is not documented publicly: a verification by
// measurement after the change settles it on the real robot (a wrong sign doubles delta).
//
// The wrap hides whole motor turns. When cal_offset_old - k x delta leaves [0, 2 pi), the new
// value "crosses the seam": the revolution counter still counts from the old turn, so the
// joint reads one motor turn (360 / |k| deg) off until the revolution counter is updated with the
// joint at its synchronisation mark (inferred from how resolver and counter combine;
// docs/apply.md).
#pragma once

#include <string>

namespace zerocal::apply {

constexpr double kTwoPi = 6.283185307179586;

// x wrapped into [0, 2 pi).
double wrapCalOffset(double rad);

struct CalOffsetChange {
  int joint = 0;             // 1..6
  double delta_rad = 0;      // identified arm-side offset (theta = q + delta)
  double transmission = 0;   // k, signed
  double old_rad = 0;        // the present cal_offset
  double unwrapped_rad = 0;  // old - k x delta
  double new_rad = 0;        // wrapped into [0, 2 pi)
  int turns = 0;             // (new - unwrapped) / 2 pi: 0 unless the seam is crossed

  bool crossesSeam() const { return turns != 0; }
  // The arm-side error, rad, that a revolution counter left on the old turn causes: the joint
  // reads this much too little (theta = q + error) until the counter is updated.
  double turnErrorRad() const;
};

// Throws InputError for a transmission below 1 in magnitude, a joint outside 1..6, an old value
// outside [0, 2 pi) or a non-finite number.
CalOffsetChange calOffsetChange(int joint, double delta_rad, double transmission, double old_rad);

// The formula with every sign written, for the technician, e.g.
// "cal_offset_3 = wrap(5.546490 - (+120) x (+0.00872665 rad)) = wrap(4.499292) = 4.499292 rad"
std::string formulaText(const CalOffsetChange& change);

// The value as the controller writes it in MOC.cfg: 6 significant digits, as in its backups
// ("0.728257", "6.07245"). 6 digits of a value below 2 pi resolve 5e-6 rad on the motor side,
// 4e-8 rad (2e-6 deg) on the arm for a transmission of 120.
std::string mocNumber(double rad);

}  // namespace zerocal::apply
