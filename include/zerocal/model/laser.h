// The laser line fixed on the flange, in the flange frame (DH frame 6), and its minimal
// 4-parameter deviation from a nominal line.
//
// Given the nominal unit direction n and nominal point p0, an orthonormal basis (e1, e2) of the
// plane normal to n is fixed once (e1 is the flange axis least aligned with n, made orthogonal;
// e2 = n x e1; for the default n = flange x, e1 = flange y and e2 = flange z). The four
// parameters kappa = (s1, s2, o1, o2) give
//
//   direction d = normalise(n + s1 e1 + s2 e2)      (s1, s2: slopes, dimensionless)
//   point     p = p0 + o1 e1 + o2 e2                (o1, o2: millimetres)
//
// which is smooth and full rank at kappa = 0 (unlike the paper's (M_E, N_E, y0E, z0E) with P_E
// dependent, which is singular when the beam is exactly along x). For the default nominal the
// parameters are the paper's N_E/M_E, P_E/M_E, y0E, z0E; the point lies in the plane through p0
// normal to n, the paper's x0E = 0.
#pragma once

#include <Eigen/Core>
#include <string>

#include "zerocal/model/kinematics.h"

namespace zerocal {

constexpr int kLaserParamCount = 4;

class LaserModel {
 public:
  // Throws ConfigError when the nominal direction is not a finite non-zero vector.
  explicit LaserModel(const Eigen::Vector3d& nominal_direction = Eigen::Vector3d::UnitX(),
                      const Eigen::Vector3d& nominal_point = Eigen::Vector3d::Zero());

  // The line in the flange frame for parameters kappa[4].
  template <typename T>
  void line(const T* kappa, Vec3<T>* point, Vec3<T>* direction) const {
    Vec3<T> d = n_.cast<T>() + kappa[0] * e1_.cast<T>() + kappa[1] * e2_.cast<T>();
    *direction = d / d.norm();
    *point = p0_.cast<T>() + kappa[2] * e1_.cast<T>() + kappa[3] * e2_.cast<T>();
  }

  // Inverse of line(): the parameters of a given flange-frame line (direction need not be unit;
  // the point is moved along the line into the parameter plane). Requires dot(direction, n) > 0.
  Eigen::Vector4d parametersOf(const Eigen::Vector3d& point,
                               const Eigen::Vector3d& direction) const;

  const Eigen::Vector3d& nominalDirection() const { return n_; }
  const Eigen::Vector3d& nominalPoint() const { return p0_; }
  const Eigen::Vector3d& e1() const { return e1_; }
  const Eigen::Vector3d& e2() const { return e2_; }

  // Parameter names as they appear in reports and JSON.
  static const char* parameterName(int i);

 private:
  Eigen::Vector3d n_, p0_, e1_, e2_;
};

}  // namespace zerocal
