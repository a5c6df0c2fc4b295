#include "zerocal/model/laser.h"

#include <cmath>

#include "zerocal/error.h"

namespace zerocal {

LaserModel::LaserModel(const Eigen::Vector3d& nominal_direction,
                       const Eigen::Vector3d& nominal_point)
    : p0_(nominal_point) {
  const double norm = nominal_direction.norm();
  if (!std::isfinite(norm) || norm < 1e-9 || !nominal_point.allFinite())
    throw ConfigError("laser", {"the nominal laser direction must be a finite non-zero vector "
                                "and the nominal point finite"});
  n_ = nominal_direction / norm;
  // e1: the flange axis least aligned with n, made orthogonal to it. Ties go to the earlier
  // axis after x, so that the default n = x gives e1 = y, e2 = z (the paper's y0E, z0E).
  int best = 1;
  for (int axis : {2, 0})
    if (std::abs(n_[axis]) < std::abs(n_[best]) - 1e-12) best = axis;
  const Eigen::Vector3d ref = Eigen::Vector3d::Unit(best);
  e1_ = (ref - ref.dot(n_) * n_).normalized();
  e2_ = n_.cross(e1_);
}

Eigen::Vector4d LaserModel::parametersOf(const Eigen::Vector3d& point,
                                         const Eigen::Vector3d& direction) const {
  const Eigen::Vector3d d = direction / direction.dot(n_);  // scale so that n-component is 1
  // Move the point along the line into the plane through p0 normal to n.
  const Eigen::Vector3d p = point - (point - p0_).dot(n_) * d;
  return {d.dot(e1_), d.dot(e2_), (p - p0_).dot(e1_), (p - p0_).dot(e2_)};
}

const char* LaserModel::parameterName(int i) {
  static const char* names[kLaserParamCount] = {"laser_slope_1", "laser_slope_2",
                                                "laser_offset_1_mm", "laser_offset_2_mm"};
  return names[i];
}

}  // namespace zerocal
