#include "zerocal/sim/world.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "stored_plan.h"
#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace {

// At q = 0 the flange is at (815, 0, 1186.5) with its x axis along base -z (irb1600.md): a beam
// along flange x goes straight down.
World downwardBeam() {
  World w;
  w.robot = builtinIrb1600();
  w.psd_position_mm = Eigen::Vector3d(825, -20, 400);
  return w;
}

TEST(World, BeamStraightDownHitsTheHorizontalPsdBelowTheFlange) {
  const auto hit = beamHit(downwardBeam(), Joints{});
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->spot.u_mm, -10, 1e-9);
  EXPECT_NEAR(hit->spot.v_mm, 20, 1e-9);
  EXPECT_NEAR(hit->range_mm, 786.5, 1e-9);
}

TEST(World, PsdRotationMapsIntoItsOwnFrame) {
  World w = downwardBeam();
  // Rotated 90 deg about z: PSD x = base y, PSD y = base -x.
  w.psd_rotation = Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto hit = beamHit(w, Joints{});
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->spot.u_mm, 20, 1e-9);
  EXPECT_NEAR(hit->spot.v_mm, 10, 1e-9);
}

TEST(World, TrueOffsetsAndExtraErrorAddToTheControllerJoints) {
  World w = downwardBeam();
  w.true_offsets_deg = {0.3, -0.2, 0.1, 0.5, -0.4, 0.25};
  const Joints q{1, 2, 3, 4, 5, 6}, extra{1e-3, 0, 0, 0, -2e-3, 0};
  World zero = w;
  zero.true_offsets_deg = Joints{};
  Joints shifted;
  for (int i = 0; i < kJointCount; ++i) shifted[i] = q[i] + w.true_offsets_deg[i] + extra[i];
  const auto a = beamHit(w, q, extra), b = beamHit(zero, shifted);
  ASSERT_TRUE(a && b);
  EXPECT_NEAR(a->spot.u_mm, b->spot.u_mm, 1e-9);
  EXPECT_NEAR(a->spot.v_mm, b->spot.v_mm, 1e-9);
  const auto nominal = beamHit(zero, q);
  EXPECT_GT(
      std::abs(a->spot.u_mm - nominal->spot.u_mm) + std::abs(a->spot.v_mm - nominal->spot.v_mm),
      1.0);
}

TEST(World, ParallelOrBackwardBeamMisses) {
  World w = downwardBeam();
  w.psd_position_mm.z() = 1500;  // above the flange, beam points down
  EXPECT_FALSE(beamHit(w, Joints{}));
  w = downwardBeam();
  w.psd_rotation = Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_FALSE(beamHit(w, Joints{}));  // plane contains the beam direction
}

TEST(World, RandomWorldIsReproducibleBoundedAndReachable) {
  const World a = randomWorld(42), b = randomWorld(42), c = randomWorld(43);
  EXPECT_EQ(a.true_offsets_deg, b.true_offsets_deg);
  EXPECT_TRUE(a.psd_rotation.isApprox(b.psd_rotation));
  EXPECT_NE(a.true_offsets_deg, c.true_offsets_deg);
  for (double d : a.true_offsets_deg) EXPECT_LE(std::abs(d), 1.0);
  EXPECT_NEAR(a.laser_direction.norm(), 1.0, 1e-12);
  EXPECT_LT((a.psd_position_mm - Eigen::Vector3d(900, -50, 400)).norm(), 40);
  EXPECT_TRUE(beamHit(a, Joints{}));
}

TEST(World, ParsesAFile) {
  const World w = parseWorld(R"(
robot: builtin
true_offsets_deg: [0.1, -0.2, 0.3, -0.4, 0.5, -0.6]
laser: {point_mm: [0, 1, 2], direction: [2, 0, 0]}
psd: {position_mm: [900, -50, 400], rpy_deg: [0, 0, 90]}
noise: {repeatability_deg: 0.001, psd_mm: 0.002}
)",
                             "test");
  EXPECT_EQ(w.true_offsets_deg[5], -0.6);
  EXPECT_TRUE(w.laser_direction.isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(w.psd_rotation.col(0).isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_EQ(w.noise.repeatability_deg, 0.001);
  EXPECT_EQ(w.robot.limits[2].upper_deg, 65);
}

TEST(World, TheShippedExampleLoadsAndItsBeamHitsThePsdPlane) {
  const World w = loadWorld(ZEROCAL_SOURCE_DIR "/config/worlds/example.yaml");
  EXPECT_EQ(w.true_offsets_deg[3], -0.65);
  EXPECT_TRUE(beamHit(w, Joints{0, 0, 0, 0, 30, 0}));
}

TEST(World, ReportsEveryProblemAtOnce) {
  try {
    parseWorld(R"(
robot: no/such/robot.yaml
true_offsets_deg: [0.1, 0.2]
laser: {point_mm: [0, 0, x], direction: [0, 0, 0]}
noise: {repeatability_deg: -1}
)",
               "bad.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_GE(e.problems().size(), 6u) << e.what();  // robot, offsets, point, direction, psd, noise
  }
  EXPECT_THROW(loadWorld("/nonexistent/world.yaml"), ConfigError);
}

// A world file of any shape is read or refused with its problems, each with the file's line:
// never a parser's exception (which aborted zerocal-sim) or a value no cell has.
TEST(World, AnyShapeOfFileIsAConfigurationErrorWithItsLine) {
  const auto problemsOf = [](const std::string& text) -> std::vector<std::string> {
    try {
      parseWorld(text, "w.yaml");
    } catch (const ConfigError& e) {
      return e.problems();
    }
    return {};
  };
  const auto has = [](const std::vector<std::string>& problems, const std::string& text) {
    for (const std::string& p : problems)
      if (p.find(text) != std::string::npos) return true;
    return false;
  };
  const std::string valid =
      "true_offsets_deg: [0, 0, 0, 0, 0, 0]\n"
      "laser: {point_mm: [0, 0, 0], direction: [1, 0, 0]}\n"
      "psd: {position_mm: [900, -50, 400], rpy_deg: [0, 0, 0]}\n";
  ASSERT_TRUE(problemsOf(valid).empty());
  // Cut short in the middle of a section: the section is a word, not a map; said once.
  const auto cut = problemsOf("robot: builtin\nnoise:\n  repeatability_deg");
  EXPECT_TRUE(has(cut, "w.yaml:3: noise: must be a map"));
  EXPECT_EQ(
      std::count_if(cut.begin(), cut.end(),
                    [](const std::string& p) { return p.find("noise") != std::string::npos; }),
      1)
      << ::testing::PrintToString(cut);
  for (const char* section : {"noise", "dh_errors", "compliance", "thermal", "gross_errors"}) {
    EXPECT_TRUE(has(problemsOf(valid + section + ": 5\n"),
                    std::string("w.yaml:4: ") + section + ": must be a map"))
        << section;
    EXPECT_FALSE(problemsOf(valid + section + ": [1, 2]\n").empty()) << section;
  }
  EXPECT_TRUE(has(problemsOf("laser: 5\npsd: [1]\n"), "w.yaml:1: laser: must be a map"));
  EXPECT_TRUE(has(problemsOf("laser: 5\npsd: [1]\n"), "w.yaml:2: psd: must be a map"));
  EXPECT_TRUE(has(problemsOf(valid + "robot: {a: 1}\n"), "w.yaml:4: robot: must be"));
  // Numbers no cell has, and a placement with no int to be.
  EXPECT_TRUE(has(problemsOf("true_offsets_deg: [1e300, 0, 0, 0, 0, 0]\n" + valid.substr(37)),
                  "w.yaml:1: true_offsets_deg[0]: must be a number within +-360"));
  EXPECT_TRUE(has(problemsOf(valid + "noise: {repeatability_deg: 1e308}\n"),
                  "w.yaml:4: noise.repeatability_deg: must lie within"));
  EXPECT_TRUE(has(problemsOf(valid + "placements: [{placement: 1e300, planned_mm: [0, 0, 0], "
                                     "position_mm: [0, 0, 0], rpy_deg: [0, 0, 0]}]\n"),
                  "placements[0].placement: must"));
  EXPECT_TRUE(has(problemsOf(valid + "{a: 1}: 2\n"), "w.yaml:4: (not a word): unknown key"));
}

// The default repeatability is issue 5's "0.02 mm sigma": the per-axis standard deviation of the
// flange (TCP) position, sqrt(trace(J S J^T) / 3) with S = sigma^2 I per joint, averaged over the
// optimal plans of several random worlds (stored in tests/data/plans: made for each world's true
// PSD centre and normal).
TEST(World, DefaultRepeatabilityIsTwoHundredthsOfAMillimetreAtTheTcp) {
  const double sigma_deg = WorldNoise{}.repeatability_deg;
  double sum = 0;
  int poses = 0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const World w = randomWorld(seed);
    for (const Pose& pose :
         testing::storedPlan("realistic-" + std::to_string(seed) + "-true-centre")) {
      constexpr double kH = 1e-4;  // deg
      double trace = 0;
      for (int j = 0; j < kJointCount; ++j) {
        Joints plus = pose.q_deg, minus = pose.q_deg;
        plus[j] += kH;
        minus[j] -= kH;
        const Eigen::Vector3d column =
            (flangePoseDeg(w.robot, plus).p - flangePoseDeg(w.robot, minus).p) / (2 * kH);
        trace += column.squaredNorm() * sigma_deg * sigma_deg;
      }
      sum += std::sqrt(trace / 3);
      ++poses;
    }
  }
  const double tcp_sigma_mm = sum / poses;
  std::printf("repeatability %.2e deg per joint: %.4f mm per axis at the TCP (%d poses)\n",
              sigma_deg, tcp_sigma_mm, poses);
  EXPECT_NEAR(tcp_sigma_mm, 0.020, 0.002);
}

}  // namespace
}  // namespace zerocal
