#include "zerocal/apply/motor_calibration.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>

#include "zerocal/error.h"

namespace zerocal::apply {

double wrapCalOffset(double rad) {
  double w = rad - kTwoPi * std::floor(rad / kTwoPi);
  // floor's rounding can land exactly on 2 pi for a tiny negative input.
  if (w >= kTwoPi) w -= kTwoPi;
  return w;
}

double CalOffsetChange::turnErrorRad() const { return kTwoPi * turns / transmission; }

CalOffsetChange calOffsetChange(int joint, double delta_rad, double transmission, double old_rad) {
  const std::string where = "joint " + std::to_string(joint) + ": ";
  if (joint < 1 || joint > 6) throw InputError(where + "no such joint (1..6)");
  if (!std::isfinite(delta_rad)) throw InputError(where + "the offset is not a number");
  if (!std::isfinite(transmission) || std::abs(transmission) < 1.0)
    throw InputError(where + "the transmission must be a signed ratio of at least 1 in magnitude");
  if (!(old_rad >= 0.0 && old_rad < kTwoPi))
    throw InputError(where + "the present cal_offset " + std::to_string(old_rad) +
                     " rad is outside [0, 2 pi): not a value the controller holds");
  CalOffsetChange c;
  c.joint = joint;
  c.delta_rad = delta_rad;
  c.transmission = transmission;
  c.old_rad = old_rad;
  c.unwrapped_rad = old_rad - transmission * delta_rad;
  c.new_rad = wrapCalOffset(c.unwrapped_rad);
  c.turns = static_cast<int>(std::lround((c.new_rad - c.unwrapped_rad) / kTwoPi));
  return c;
}

std::string formulaText(const CalOffsetChange& c) {
  std::string s = fmt::format(
      FMT_STRING("cal_offset_{} = wrap({:.6f} - ({:+g}) x ({:+.8f} rad)) = wrap({:+.6f}) = {:.6f} "
                 "rad"),
      c.joint, c.old_rad, c.transmission, c.delta_rad, c.unwrapped_rad, c.new_rad);
  if (c.crossesSeam())
    s += fmt::format(FMT_STRING(" ({:+d} motor turn{}: crosses the 0 / 2 pi seam)"), c.turns,
                     std::abs(c.turns) == 1 ? "" : "s");
  return s;
}

std::string mocNumber(double rad) { return fmt::format(FMT_STRING("{:.6G}"), rad); }

}  // namespace zerocal::apply
