#include "zerocal/model/laser.h"

#include <gtest/gtest.h>

#include "zerocal/error.h"

namespace zerocal {
namespace {

TEST(Laser, DefaultNominalIsFlangeXWithBasisYZ) {
  LaserModel laser;
  EXPECT_TRUE(laser.e1().isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(laser.e2().isApprox(Eigen::Vector3d::UnitZ()));
  const double kappa[4] = {0, 0, 0, 0};
  Eigen::Vector3d p, d;
  laser.line(kappa, &p, &d);
  EXPECT_TRUE(d.isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(p.isZero());
}

TEST(Laser, ParametersOfInvertsLine) {
  LaserModel laser(Eigen::Vector3d(0.2, 0.1, 1.0), Eigen::Vector3d(1, 2, 3));
  const double kappa[4] = {0.01, -0.02, 0.5, -0.3};
  Eigen::Vector3d p, d;
  laser.line(kappa, &p, &d);
  const Eigen::Vector4d back = laser.parametersOf(p + 17.0 * d, 3.0 * d);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(back[i], kappa[i], 1e-12);
}

TEST(Laser, RejectsZeroDirection) {
  EXPECT_THROW(LaserModel(Eigen::Vector3d::Zero()), ConfigError);
}

}  // namespace
}  // namespace zerocal
