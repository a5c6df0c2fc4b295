// The realistic simulated world: the arm's link errors, compliance and warming, the PSD known only
// as configured and taught, gross errors at their rate; and the ideal world kept exact.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "zerocal/error.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/model/robot.h"
#include "zerocal/sim/sim_controller.h"
#include "zerocal/sim/world.h"

namespace zerocal {
namespace {

double angleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() * kRadToDeg;
}

Joints randomPose(std::mt19937_64& rng) {
  const Robot robot = builtinIrb1600();
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Joints q;
  for (int i = 0; i < kJointCount; ++i) {
    const JointLimit& l = robot.limits[i];
    q[i] = l.lower_deg + 5 + (l.upper_deg - l.lower_deg - 10) * unit(rng);
  }
  return q;
}

TEST(RealisticWorld, DrawsEveryImperfectionWithItsSpecifiedMagnitude) {
  double sum_len_sq = 0, sum_twist_sq = 0;
  int lengths = 0, twists = 0;
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    const World w = randomWorld(seed), ideal = randomWorld(seed, WorldKind::kIdeal);
    // What calibration must find and the PSD's true pose are the ideal world's.
    EXPECT_EQ(w.true_offsets_deg, ideal.true_offsets_deg);
    EXPECT_EQ(w.laser_point_mm, ideal.laser_point_mm);
    EXPECT_EQ(w.psd_position_mm, ideal.psd_position_mm);
    EXPECT_EQ(w.psd_rotation, ideal.psd_rotation);
    for (const DhError& e : w.dh_errors) {
      sum_len_sq += e.a_mm * e.a_mm + e.d_mm * e.d_mm;
      sum_twist_sq += e.alpha_deg * e.alpha_deg;
      lengths += 2;
      ++twists;
    }
    EXPECT_GE(w.compliance.joint2_sag_deg, 0.003);
    EXPECT_LE(w.compliance.joint2_sag_deg, 0.010);
    EXPECT_GE(w.compliance.joint3_sag_deg, 0.002);
    EXPECT_LE(w.compliance.joint3_sag_deg, 0.006);
    EXPECT_EQ(w.thermal.expansion_per_k, 23e-6);
    EXPECT_GE(w.thermal.rise_k, 3);
    EXPECT_LE(w.thermal.rise_k, 10);
    const double psd_off_deg = angleDeg(w.psd_rotation, w.psd_rotation_configured);
    EXPECT_GE(psd_off_deg, 1 - 1e-9);
    EXPECT_LE(psd_off_deg, 3 + 1e-9);
    const double taught_off_mm = (w.psd_centre_taught_mm - w.psd_position_mm).norm();
    EXPECT_GE(taught_off_mm, 1 - 1e-9);
    EXPECT_LE(taught_off_mm, 5 + 1e-9);
    EXPECT_EQ(w.gross.stray_light_rate, kDefaultGrossRate);
    EXPECT_EQ(w.gross.unsettled_rate, kDefaultGrossRate);
    // The true masses: around the robot file's split, never it exactly.
    const auto& share = w.compliance.mass_share;
    EXPECT_NEAR(share[0] + share[1] + share[2], 1.0, 1e-12);
    const Compliance nominal;
    for (int i = 0; i < 3; ++i) {
      EXPECT_NE(share[i], nominal.mass_share[i]);
      EXPECT_GT(share[i], nominal.mass_share[i] * 0.75 / 1.25 - 1e-12);
      EXPECT_LT(share[i], nominal.mass_share[i] * 1.25 / 0.75 + 1e-12);
    }
    for (int i = 0; i < 2; ++i)
      EXPECT_LE(std::abs(w.compliance.mass_position[i] - nominal.mass_position[i]),
                kMassPositionSpread);
  }
  // 480 lengths and 240 twists: the sample sigma within 15% of the specified one.
  EXPECT_NEAR(std::sqrt(sum_len_sq / lengths), kLinkLengthSigmaMm, 0.15 * kLinkLengthSigmaMm);
  EXPECT_NEAR(std::sqrt(sum_twist_sq / twists), kLinkTwistSigmaDeg, 0.15 * kLinkTwistSigmaDeg);
}

TEST(RealisticWorld, IsTheSameForTheSameSeedAndDiffersBetweenSeeds) {
  const World a = randomWorld(7), b = randomWorld(7), c = randomWorld(8);
  EXPECT_EQ(worldHash(a), worldHash(b));
  EXPECT_NE(worldHash(a), worldHash(c));
  EXPECT_NE(worldHash(a), worldHash(randomWorld(7, WorldKind::kIdeal)));
  EXPECT_EQ(a.dh_errors[1].a_mm, b.dh_errors[1].a_mm);
  EXPECT_NE(a.dh_errors[1].a_mm, c.dh_errors[1].a_mm);
  const Joints q{10, 20, -10, 30, 40, 50};
  const auto ha = beamHit(a, q, {}, 100), hb = beamHit(b, q, {}, 100);
  ASSERT_TRUE(ha && hb);
  EXPECT_EQ(ha->spot.u_mm, hb->spot.u_mm);
  EXPECT_EQ(ha->spot.v_mm, hb->spot.v_mm);
}

// An uncalibrated IRB 1600 is within 0.65 mm (Slamani, Nubiola and Bonev 2012) with its joint
// zeros set by ABB: the realistic arm without offsets must stay in that class, not far below it
// (then the model errors would be a token) nor above it.
TEST(RealisticWorld, TheArmIsAsAccurateAsAnUncalibratedIrb1600) {
  std::mt19937_64 rng(99);
  double sum_sq = 0, worst = 0;
  int n = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    World w = randomWorld(seed);
    w.true_offsets_deg = Joints{};
    for (int k = 0; k < 50; ++k) {
      const Joints q = randomPose(rng);
      const double e = (trueFlangePositionMm(w, q) - flangePoseDeg(w.robot, q).p).norm();
      sum_sq += e * e;
      worst = std::max(worst, e);
      ++n;
    }
  }
  const double rms = std::sqrt(sum_sq / n);
  std::printf("flange position error of the realistic arm: RMS %.3f mm, worst %.3f mm\n", rms,
              worst);
  EXPECT_GT(rms, 0.15);
  EXPECT_LT(rms, 0.65);
}

TEST(RealisticWorld, GravitySagFollowsTheTorqueOfThePose) {
  World w = randomWorld(3, WorldKind::kIdeal);
  w.compliance = {0.01, 0.005};
  // Upper arm and forearm horizontal, pointing along base x: the largest torque on joint 2; the
  // arm droops, so the flange comes down.
  const Joints stretched{0, 90, -90, 0, 0, 0};
  const Joints sag = gravitySagDeg(w, stretched);
  EXPECT_NEAR(std::abs(sag[1]), 0.01, 0.002);
  EXPECT_LT(trueFlangePositionMm(w, stretched).z(),
            trueFlangePositionMm(randomWorld(3, WorldKind::kIdeal), stretched).z() - 0.05);
  // Upper arm upright, forearm straight up: no torque on joints 2 and 3 (up to the a1 offset).
  const Joints upright{0, 0, -90, 0, 0, 0};
  const Joints none = gravitySagDeg(w, upright);
  EXPECT_LT(std::abs(none[1]), 0.1 * std::abs(sag[1]));
  EXPECT_LT(std::abs(none[2]), 1e-6);
  for (int j : {0, 3, 4, 5}) EXPECT_EQ(sag[j], 0.0);
}

// The sag is a constant compliance times the gravity torque of the true masses: proportional
// to the torque the robot file's model computes where the masses are the nominal ones, and
// never beyond its magnitude.
TEST(RealisticWorld, GravitySagIsAConstantComplianceTimesTheTorque) {
  World w = randomWorld(3, WorldKind::kIdeal);
  w.compliance.joint2_sag_deg = 0.01;
  w.compliance.joint3_sag_deg = 0.005;
  std::mt19937_64 rng(21);
  const Joints stretched{0, 90, -90, 0, 0, 0};
  const auto torque_stretched = gravityTorqueKnm(w.robot, w.robot.masses, stretched);
  const Joints sag_stretched = gravitySagDeg(w, stretched);
  const double ratio2 = sag_stretched[1] / torque_stretched[0];
  const double ratio3 = sag_stretched[2] / torque_stretched[1];
  for (int k = 0; k < 30; ++k) {
    const Joints q = randomPose(rng);
    const Joints sag = gravitySagDeg(w, q);
    const auto torque = gravityTorqueKnm(w.robot, w.robot.masses, q);
    EXPECT_LE(std::abs(sag[1]), 0.01 + 1e-12);
    EXPECT_LE(std::abs(sag[2]), 0.005 + 1e-12);
    EXPECT_NEAR(sag[1], ratio2 * torque[0], 1e-12);
    EXPECT_NEAR(sag[2], ratio3 * torque[1], 1e-12);
  }
}

TEST(RealisticWorld, ThermalGrowthScalesTheArmSlowlyOverTheSession) {
  World w = randomWorld(4, WorldKind::kIdeal);
  w.true_offsets_deg = Joints{};
  w.thermal = {23e-6, 8, 3600};
  const Joints q{15, 30, -20, 10, 45, 0};
  const Eigen::Vector3d p0 = trueFlangePositionMm(w, q, 0);
  EXPECT_TRUE(p0.isApprox(flangePoseDeg(w.robot, q).p, 1e-15));
  for (double t : {90.0, 3600.0, 36000.0}) {
    const double growth = 1 + 23e-6 * 8 * (1 - std::exp(-t / 3600));
    const Eigen::Vector3d p = trueFlangePositionMm(w, q, t);
    EXPECT_NEAR((p - growth * p0).norm(), 0, 1e-9) << t;
  }
  // Over a 90 s session the flange moves a few micrometres, not more.
  const double moved_um = (trueFlangePositionMm(w, q, 90) - p0).norm() * 1e3;
  EXPECT_GT(moved_um, 1);
  EXPECT_LT(moved_um, 20);
}

// The ideal world is the world of before: its beam is the nominal arm's, to the last bit.
TEST(IdealWorld, ReproducesTheNominalArmExactly) {
  const World w = randomWorld(11, WorldKind::kIdeal);
  std::mt19937_64 rng(5);
  for (int k = 0; k < 20; ++k) {
    const Joints q = randomPose(rng);
    Joints extra{};
    extra[k % kJointCount] = 1e-3;
    Joints delta;
    for (int i = 0; i < kJointCount; ++i) delta[i] = w.true_offsets_deg[i] + extra[i];
    const Frame<double> f = flangePoseDeg(w.robot, q, delta);
    const Eigen::Vector3d p = f.apply(w.laser_point_mm);
    const Eigen::Vector3d d = (f.R * w.laser_direction).normalized();
    const Eigen::Vector3d n = w.psd_rotation.col(2);
    const auto hit = beamHit(w, q, extra, 1000.0);  // no warming in the ideal world
    if (std::abs(n.dot(d)) < 1e-9 || !(n.dot(w.psd_position_mm - p) / n.dot(d) > 0)) {
      EXPECT_FALSE(hit);
      continue;
    }
    ASSERT_TRUE(hit);
    const double t = n.dot(w.psd_position_mm - p) / n.dot(d);
    const Eigen::Vector3d local = w.psd_rotation.transpose() * (p + t * d - w.psd_position_mm);
    EXPECT_EQ(hit->spot.u_mm, local.x());
    EXPECT_EQ(hit->spot.v_mm, local.y());
  }
  EXPECT_EQ(w.psd_rotation_configured, w.psd_rotation);
  EXPECT_EQ(w.psd_centre_taught_mm, w.psd_position_mm + Eigen::Vector3d(3, -3, 3));
  EXPECT_EQ(w.gross.stray_light_rate, 0);
  EXPECT_EQ(w.gross.unsettled_rate, 0);
}

// One error put at a pose: there the first time the arm rests near it, not when it comes back
// (a measurement made again), and every other pose drawn as without it.
TEST(GrossErrors, OneForcedErrorStrikesItsPoseOnceAndNothingElse) {
  const std::vector<Joints> poses = {
      {0, 10, 20, 0, 60, 0}, {30, 0, 10, 20, 40, 0}, {-20, 15, 5, -30, 70, 10}};
  for (const auto kind : {GrossErrors::Kind::kStrayLight, GrossErrors::Kind::kUnsettled}) {
    GrossErrors plain;  // no rates: nothing but the forced error may appear
    GrossErrors forced = plain;
    forced.forced_at_deg = poses[1];
    forced.forced_kind = kind;
    std::mt19937_64 rng_plain(5), rng_forced(5);
    GrossState s_plain, s_forced;
    // Pose 0; 3 deg from pose 1 (a pose of its own: not struck); pose 1 itself, within 5 deg of
    // the pose before (struck, on a draw of its own); pose 2; pose 1 again (not struck twice).
    const std::vector<int> visits = {0, 1, 1, 2, 1};
    for (std::size_t v = 0; v < visits.size(); ++v) {
      Joints q = poses[visits[v]];
      if (v == 1) q[5] += 3.0;
      updateGross(plain, q, rng_plain, &s_plain);
      updateGross(forced, q, rng_forced, &s_forced);
      const bool struck = v == 2;
      const bool stray = s_forced.stray_light_mm.norm() > 0;
      const bool unsettled =
          Eigen::Map<const Eigen::Matrix<double, 6, 1>>(s_forced.unsettled_deg.data())
              .cwiseAbs()
              .maxCoeff() > 0;
      EXPECT_EQ(stray, struck && kind == GrossErrors::Kind::kStrayLight) << v;
      EXPECT_EQ(unsettled, struck && kind == GrossErrors::Kind::kUnsettled) << v;
      EXPECT_EQ(s_plain.stray_light_mm.norm(), 0.0);
    }
    // The forced pose took one draw (five numbers) more than the plain world; no other changed.
    EXPECT_EQ(s_forced.draws, s_plain.draws + 1);
    for (int k = 0; k < 5; ++k) rng_plain();
    EXPECT_EQ(rng_plain(), rng_forced());
  }
  // A world file says it, and the hash tells the two worlds apart.
  World w = randomWorld(3);
  const std::string before = worldHash(w);
  w.gross.forced_at_deg = poses[2];
  w.gross.forced_kind = GrossErrors::Kind::kUnsettled;
  const World back = parseWorld(worldYaml(w), "test");
  ASSERT_TRUE(back.gross.forced_at_deg);
  EXPECT_EQ(*back.gross.forced_at_deg, poses[2]);
  EXPECT_EQ(back.gross.forced_kind, GrossErrors::Kind::kUnsettled);
  EXPECT_NE(worldHash(w), before);
  EXPECT_THROW(parseGrossKind("cosmic_ray"), InputError);
}

// A world file names its robot file as it is, even a path YAML would read otherwise.
TEST(WorldFile, NamesARobotFileWhosePathYamlWouldMisreadAsItIs) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("zerocal-world-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  Robot robot = builtinIrb1600();
  robot.name = "cell 3's arm";
  std::ofstream(dir / "robot: cell #3.yaml") << robotYaml(robot);
  World w = randomWorld(3);
  w.robot = robot;
  const std::string text = worldYaml(w, "robot: cell #3.yaml");
  const World back = parseWorld(text, "test", dir.string());
  std::filesystem::remove_all(dir);
  EXPECT_EQ(back.robot.name, "cell 3's arm") << text;
  EXPECT_EQ(back.true_offsets_deg, w.true_offsets_deg);
  EXPECT_EQ(back.psd_position_mm, w.psd_position_mm);
}

TEST(GrossErrors, AppearAtTheConfiguredRatePerPose) {
  GrossErrors g;
  g.stray_light_rate = 0.1;
  g.unsettled_rate = 0.2;
  std::mt19937_64 rng(17);
  GrossState state;
  constexpr int kPoses = 20000;
  int stray = 0, unsettled = 0;
  Joints q{};
  for (int k = 0; k < kPoses; ++k) {
    q[k % 3] += (k % 2 == 0 ? 1 : -1) * 7.0;  // a new pose, more than 5 deg away
    updateGross(g, q, rng, &state);
    // Servo moves near the pose keep what was drawn.
    const GrossState drawn = state;
    Joints near = q;
    near[4] += 2.0;
    updateGross(g, near, rng, &state);
    ASSERT_EQ(state.stray_light_mm, drawn.stray_light_mm);
    ASSERT_EQ(state.unsettled_deg, drawn.unsettled_deg);
    if (state.stray_light_mm.norm() > 0) {
      ++stray;
      EXPECT_NEAR(state.stray_light_mm.norm(), g.stray_light_mm, 1e-12);
    }
    int joints = 0;
    for (double e : state.unsettled_deg)
      if (e != 0) {
        ++joints;
        EXPECT_EQ(std::abs(e), g.unsettled_deg);
      }
    EXPECT_LE(joints, 1);
    unsettled += joints;
  }
  EXPECT_EQ(state.draws, kPoses);
  // Binomial: within 4 standard deviations.
  EXPECT_NEAR(stray, 0.1 * kPoses, 4 * std::sqrt(kPoses * 0.1 * 0.9));
  EXPECT_NEAR(unsettled, 0.2 * kPoses, 4 * std::sqrt(kPoses * 0.2 * 0.8));
}

// On the simulated controller: stray light moves the spot the detector sees, an unsettled reading
// moves the arm, both for the whole pose.
TEST(GrossErrors, TheSimulatedControllerShowsThemToTheDetector) {
  SimControllerOptions o;
  o.world = randomWorld(7);
  o.world.noise.repeatability_deg = 0;
  o.world.gross.stray_light_rate = 1;
  o.world.gross.unsettled_rate = 1;
  SimController sim(o);
  sim.start();
  Irc5Options c;
  c.host = "127.0.0.1";
  c.port = sim.port();
  c.robot = o.world.robot;
  Irc5Client client(c);
  client.connect();
  client.moveJoints({0, 10, 10, 0, 40, 0});
  const Joints error = sim.moveErrorDeg();
  double moved = 0;
  for (double e : error) moved += std::abs(e);
  EXPECT_NEAR(moved, o.world.gross.unsettled_deg, 1e-12);
  const auto seen = sim.beamHitNow();
  const auto arm = beamHit(sim.world(), sim.commandedJoints(), error, sim.simTimeS());
  ASSERT_TRUE(seen && arm);
  EXPECT_NEAR(std::hypot(seen->spot.u_mm - arm->spot.u_mm, seen->spot.v_mm - arm->spot.v_mm),
              o.world.gross.stray_light_mm, 1e-9);
  // The same request the external backend's detector asks.
  const auto spot = client.readSimBeamSpot();
  ASSERT_TRUE(spot);
  EXPECT_NEAR(spot->u_mm, seen->spot.u_mm, 1e-5);
  EXPECT_NEAR(spot->v_mm, seen->spot.v_mm, 1e-5);
}

TEST(WorldFile, TheTruthFileReadsBackToTheSameWorld) {
  const World w = randomWorld(12);
  const World back = parseWorld(worldYaml(w), "truth");
  for (int i = 0; i < kJointCount; ++i) {
    EXPECT_EQ(back.true_offsets_deg[i], w.true_offsets_deg[i]);
    EXPECT_EQ(back.dh_errors[i].a_mm, w.dh_errors[i].a_mm);
    EXPECT_EQ(back.dh_errors[i].d_mm, w.dh_errors[i].d_mm);
    EXPECT_EQ(back.dh_errors[i].alpha_deg, w.dh_errors[i].alpha_deg);
  }
  EXPECT_EQ(back.compliance.joint2_sag_deg, w.compliance.joint2_sag_deg);
  EXPECT_EQ(back.compliance.mass_share, w.compliance.mass_share);
  EXPECT_EQ(back.compliance.mass_position, w.compliance.mass_position);
  EXPECT_EQ(back.thermal.time_constant_s, w.thermal.time_constant_s);
  EXPECT_EQ(back.psd_centre_taught_mm, w.psd_centre_taught_mm);
  EXPECT_EQ(back.gross.unsettled_rate, w.gross.unsettled_rate);
  EXPECT_LT(angleDeg(back.psd_rotation, w.psd_rotation), 1e-10);
  EXPECT_LT(angleDeg(back.psd_rotation_configured, w.psd_rotation_configured), 1e-10);
  const Joints q{5, 25, -15, 20, 50, 10};
  const auto a = beamHit(w, q, {}, 60), b = beamHit(back, q, {}, 60);
  ASSERT_TRUE(a && b);
  EXPECT_NEAR(a->spot.u_mm, b->spot.u_mm, 1e-9);
  EXPECT_NEAR(a->spot.v_mm, b->spot.v_mm, 1e-9);
}

// A further PSD placement is off its planned pose by the world's own kind and size of error
// (placement 1's taught-centre distance and orientation angle), reproducibly; the beam meets the
// PSD where it stands; the truth file lists every placement.
TEST(WorldFile, FurtherPlacementsHaveTheWorldsErrorAndComeBackFromTheTruthFile) {
  World w = randomWorld(12);
  const Eigen::Vector3d planned(600, 650, 600);
  const PsdPlacement p = drawPlacement(w, 12, 2, planned);
  EXPECT_EQ(p.placement, 2);
  EXPECT_EQ(p.planned_mm, planned);
  const double off_mm = (w.psd_centre_taught_mm - w.psd_position_mm).norm();
  EXPECT_GT(off_mm, 0.9);
  EXPECT_NEAR((p.position_mm - planned).norm(), off_mm, 1e-9);
  EXPECT_NEAR(angleDeg(p.rotation, w.psd_rotation_configured),
              angleDeg(w.psd_rotation, w.psd_rotation_configured), 1e-9);
  EXPECT_EQ(drawPlacement(w, 12, 2, planned).position_mm, p.position_mm);  // reproducible
  EXPECT_NE(drawPlacement(w, 12, 3, planned).position_mm, p.position_mm);
  EXPECT_NE(drawPlacement(w, 13, 2, planned).position_mm, p.position_mm);
  const World ideal = randomWorld(12, WorldKind::kIdeal);  // orientation known exactly there
  EXPECT_LT(angleDeg(drawPlacement(ideal, 12, 2, planned).rotation, ideal.psd_rotation_configured),
            1e-9);

  // The beam aimed at placement 1 misses placement 2's plane where placement 1's would be hit.
  const Joints q{5, 25, -15, 20, 50, 10};
  const auto at1 = beamHit(w, q, {}, 0);
  w.placements.push_back(p);
  w.active_placement = 2;
  const auto at2 = beamHit(w, q, {}, 0);
  ASSERT_TRUE(at1 && at2);
  EXPECT_GT(std::hypot(at1->spot.u_mm - at2->spot.u_mm, at1->spot.v_mm - at2->spot.v_mm), 10.0);
  EXPECT_EQ(worldHash(w), worldHash(randomWorld(12)));  // the same cell, its PSD moved

  const World back = parseWorld(worldYaml(w), "truth");
  ASSERT_EQ(back.placements.size(), 1u);
  EXPECT_EQ(back.placements[0].placement, 2);
  EXPECT_EQ(back.placements[0].planned_mm, planned);
  EXPECT_EQ(back.placements[0].position_mm, p.position_mm);
  EXPECT_LT(angleDeg(back.placements[0].rotation, p.rotation), 1e-10);
  EXPECT_EQ(back.active_placement, 1);  // read with the PSD at placement 1
}

TEST(WorldFile, RejectsUnknownKeysAndImpossibleRatesAllAtOnce) {
  try {
    parseWorld(R"(
true_offsets_deg: [0, 0, 0, 0, 0, 0]
laser: {point_mm: [0, 0, 0], direction: [1, 0, 0]}
psd: {position_mm: [900, -50, 400], rpy_deg: [0, 0, 0], taught_centre: [1, 2, 3]}
dh_errors: {a_mm: [0, 0, 0]}
thermal: {time_constant_s: 0}
gross_errors: {stray_light_rate: 1.5, unsettled_deg: -1}
compliance_of_joints: {}
)",
               "bad.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    for (const char* expected :
         {"psd.taught_centre", "dh_errors.a_mm", "thermal.time_constant_s",
          "gross_errors.stray_light_rate", "gross_errors.unsettled_deg", "compliance_of_joints"})
      EXPECT_NE(what.find(expected), std::string::npos) << expected << " in " << what;
  }
}

TEST(WorldHash, CoversEveryImperfection) {
  const World base = randomWorld(2);
  const std::string h = worldHash(base);
  std::vector<World> changed(10, base);
  changed[8].compliance.mass_share[1] += 1e-6;
  changed[9].compliance.mass_position[0] += 1e-6;
  changed[0].dh_errors[3].d_mm += 1e-6;
  changed[1].dh_errors[5].alpha_deg += 1e-6;
  changed[2].compliance.joint3_sag_deg += 1e-6;
  changed[3].thermal.rise_k += 1e-6;
  changed[4].psd_rotation_configured(0, 1) += 1e-9;
  changed[5].psd_centre_taught_mm.z() += 1e-6;
  changed[6].gross.stray_light_rate += 1e-6;
  changed[7].gross.unsettled_deg += 1e-6;
  for (std::size_t i = 0; i < changed.size(); ++i) EXPECT_NE(worldHash(changed[i]), h) << i;
}

}  // namespace
}  // namespace zerocal
