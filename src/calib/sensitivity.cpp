#include "zerocal/calib/sensitivity.h"

#include <cmath>
#include <limits>

#include "zerocal/model/kinematics.h"

namespace zerocal {

std::array<JointSensitivity, kJointCount> spotSensitivity(const CellModel& cell,
                                                          const Joints& q_deg, double standoff_mm) {
  const CalibrationParameters nominal;
  const Line beam = laserLine(cell, q_deg, nominal);
  const Eigen::Vector3d centre = beam.point + standoff_mm * beam.direction;
  const Frame<double> flange = flangePoseDeg(cell.robot, q_deg);
  Eigen::Vector3d b1 = flange.R * cell.laser.e1();
  b1 = (b1 - b1.dot(beam.direction) * beam.direction).normalized();
  const Eigen::Vector3d b2 = beam.direction.cross(b1);
  // Where a line meets the fixed plane through `centre` normal to the unperturbed beam.
  auto spot = [&](const Line& l) {
    const double t = (centre - l.point).dot(beam.direction) / l.direction.dot(beam.direction);
    const Eigen::Vector3d hit = l.point + t * l.direction - centre;
    return Eigen::Vector2d(hit.dot(b1), hit.dot(b2));
  };
  std::array<JointSensitivity, kJointCount> out;
  const double h = 1e-4;  // deg: small enough to be linear, large enough for double precision
  for (int j = 0; j < kJointCount; ++j) {
    Joints plus = q_deg, minus = q_deg;
    plus[j] += h;
    minus[j] -= h;
    auto& s = out[j];
    s.spot_mm_per_deg =
        (spot(laserLine(cell, plus, nominal)) - spot(laserLine(cell, minus, nominal))) / (2 * h);
    s.magnitude_mm_per_deg = s.spot_mm_per_deg.norm();
    s.deg_per_20um = s.magnitude_mm_per_deg > 1e-12 ? 0.02 / s.magnitude_mm_per_deg
                                                    : std::numeric_limits<double>::infinity();
  }
  return out;
}

}  // namespace zerocal
