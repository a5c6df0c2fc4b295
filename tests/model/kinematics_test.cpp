#include "zerocal/model/kinematics.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <random>

#include "zerocal/model/builtin.h"

namespace zerocal {
namespace {

TEST(Kinematics, Irb1600FlangeAtZeroMatchesDatasheetCheckValue) {
  const Robot robot = builtinIrb1600();
  const Frame<double> f = flangePoseDeg(robot, Joints{});
  EXPECT_NEAR(f.p.x(), 815.0, 1e-9);
  EXPECT_NEAR(f.p.y(), 0.0, 1e-9);
  EXPECT_NEAR(f.p.z(), 1186.5, 1e-9);
  // Flange x points down, z along base +x (irb1600.md).
  EXPECT_TRUE(f.R.col(0).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  EXPECT_TRUE(f.R.col(2).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
}

TEST(Kinematics, Joint1RotatesTheFlangeAboutBaseZ) {
  const Robot robot = builtinIrb1600();
  const Frame<double> f = flangePoseDeg(robot, Joints{90, 0, 0, 0, 0, 0});
  EXPECT_NEAR(f.p.x(), 0.0, 1e-9);
  EXPECT_NEAR(f.p.y(), 815.0, 1e-9);
  EXPECT_NEAR(f.p.z(), 1186.5, 1e-9);
}

TEST(Kinematics, OffsetAddsToJointAngle) {
  const Robot robot = builtinIrb1600();
  const Joints q{10, 20, -30, 40, 50, 60};
  const Joints delta{0.1, -0.2, 0.3, -0.4, 0.5, -0.6};
  Joints sum;
  for (int i = 0; i < 6; ++i) sum[i] = q[i] + delta[i];
  const auto a = flangePoseDeg(robot, q, delta), b = flangePoseDeg(robot, sum);
  EXPECT_TRUE(a.p.isApprox(b.p, 1e-12));
  EXPECT_TRUE(a.R.isApprox(b.R, 1e-12));
  EXPECT_TRUE((a.R.transpose() * a.R).isIdentity(1e-12));
}

TEST(Kinematics, JetDerivativeMatchesFiniteDifference) {
  const Robot robot = builtinIrb1600();
  using J = ceres::Jet<double, 6>;
  const double q[6] = {0.3, -0.2, 0.4, 1.0, -0.7, 0.5};
  J qj[6];
  for (int i = 0; i < 6; ++i) qj[i] = J(q[i], i);
  const Frame<J> fj = flangePose(robot, qj);
  const double h = 1e-6;
  for (int i = 0; i < 6; ++i) {
    double qp[6], qm[6];
    std::copy(q, q + 6, qp);
    std::copy(q, q + 6, qm);
    qp[i] += h;
    qm[i] -= h;
    const Eigen::Vector3d fd = (flangePose(robot, qp).p - flangePose(robot, qm).p) / (2 * h);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(fj.p[k].v[i], fd[k], 1e-5) << "joint " << i;
  }
}

}  // namespace
}  // namespace zerocal
