// A session's own noise on one fixed world: the arm's per-session draws and the PSD's reading
// noise start from the session's seed; what makes the arm (its offsets, links, drawn cal_offsets)
// stays the world's. And the zero change that plays a motor replacement.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "zerocal/error.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/simulated_arm.h"
#include "zerocal/sim/world.h"
#include "zerocal/sim/zero_change.h"

namespace zerocal::sim {
namespace {

MotionModel quickModel() {
  MotionModel m;
  m.cruise_s = [](const Robot&, const Joints&, const Joints&, const MoveSpeed&) { return 0.5; };
  m.profile_s = [](double cruise_s, double) { return cruise_s + 0.25; };
  return m;
}

SimulatedArmOptions armOn(std::uint64_t seed) {
  SimulatedArmOptions o;
  o.world = randomWorld(seed);  // realistic: link errors, sag, gross errors, repeatability
  o.seed = seed;
  o.motion = quickModel();
  return o;
}

// The repeatability errors of a few moves between two poses.
std::vector<Joints> moveErrors(SimulatedArm& arm) {
  std::vector<Joints> errors;
  for (int i = 0; i < 6; ++i) {
    const MoveResult r =
        arm.moveJoints(i % 2 == 0 ? Joints{10, 5, 5, 0, 30, 0} : Joints{-10, 0, 10, 5, 40, 10});
    EXPECT_TRUE(r.moved());
    errors.push_back(arm.moveErrorDeg());
  }
  return errors;
}

TEST(SessionNoise, TheFirstSessionKeepsTheWorldsSeedAndLaterOnesDiffer) {
  EXPECT_EQ(sessionNoiseSeed(7, 0), 7u);
  EXPECT_NE(sessionNoiseSeed(7, 1), 7u);
  EXPECT_NE(sessionNoiseSeed(7, 1), sessionNoiseSeed(7, 2));
  EXPECT_NE(sessionNoiseSeed(7, 1), sessionNoiseSeed(8, 1));
  EXPECT_EQ(sessionNoiseSeed(7, 3), sessionNoiseSeed(7, 3));  // reproducible
}

TEST(SessionNoise, TwoSessionsOnOneWorldDrawDifferentNoiseOnTheSameArm) {
  constexpr std::uint64_t kWorld = 5;
  SimulatedArm first(armOn(kWorld)), second(armOn(kWorld)), replay(armOn(kWorld));
  first.reseedNoise(sessionNoiseSeed(kWorld, 0));
  second.reseedNoise(sessionNoiseSeed(kWorld, 1));
  replay.reseedNoise(sessionNoiseSeed(kWorld, 1));
  EXPECT_EQ(second.noiseSeed(), sessionNoiseSeed(kWorld, 1));

  // The arm is the same: offsets, links, what the seed drew of the controller, the world's hash.
  EXPECT_EQ(worldHash(first.world()), worldHash(second.world()));
  EXPECT_EQ(first.world().true_offsets_deg, second.world().true_offsets_deg);
  for (int j = 0; j < kJointCount; ++j) {
    EXPECT_EQ(first.world().dh_errors[j].a_mm, second.world().dh_errors[j].a_mm);
    EXPECT_EQ(first.world().dh_errors[j].alpha_deg, second.world().dh_errors[j].alpha_deg);
  }
  EXPECT_EQ(first.calOffsets(), second.calOffsets());

  // The noise is not: every move's error differs, by about the repeatability.
  const std::vector<Joints> a = moveErrors(first), b = moveErrors(second), c = moveErrors(replay);
  double rms = 0;
  int n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_NE(a[i], b[i]) << "move " << i;
    EXPECT_EQ(b[i], c[i]) << "move " << i << ": the same session seed replays the same noise";
    for (int j = 0; j < kJointCount; ++j, ++n) rms += (a[i][j] - b[i][j]) * (a[i][j] - b[i][j]);
  }
  rms = std::sqrt(rms / n);
  const double sigma = first.world().noise.repeatability_deg;
  EXPECT_GT(rms, 0.5 * sigma);  // the difference of two independent draws: sqrt(2) sigma
  EXPECT_LT(rms, 3 * sigma);
}

TEST(SessionNoise, ReseedingWithTheArmsOwnSeedChangesNothing) {
  SimulatedArm fresh(armOn(9)), reseeded(armOn(9));
  reseeded.reseedNoise(9);
  EXPECT_EQ(moveErrors(fresh), moveErrors(reseeded));
}

TEST(SessionNoise, ThePsdsReadingNoiseIsTheSessions) {
  PsdModelOptions o;
  o.seed = 105;
  PsdModel one(o), other(o), replay(o);
  other.reseed(777);
  replay.reseed(777);
  EXPECT_EQ(other.options().seed, 777u);
  const PsdSpot spot{0.1, -0.2};
  const PsdVoltages a = one.measure(spot), b = other.measure(spot), c = replay.measure(spot);
  EXPECT_NE(a.x, b.x);
  EXPECT_EQ(b.x, c.x);
  EXPECT_EQ(b.sum, c.sum);
  // The detector itself is the same: its noise-free outputs agree.
  EXPECT_EQ(one.ideal(spot).x, other.ideal(spot).x);
}

TEST(SessionNoise, AWorldFileNamesItsSessionsSeedOutsideTheHash) {
  World w = randomWorld(3);
  const std::string without = worldHash(w);
  w.noise.seed = 18446744073709551615ull;  // the largest: 64 bits unsigned
  EXPECT_EQ(worldHash(w), without);
  const World back = parseWorld(worldYaml(w), "truth");
  ASSERT_TRUE(back.noise.seed.has_value());
  EXPECT_EQ(*back.noise.seed, 18446744073709551615ull);
  EXPECT_FALSE(parseWorld(worldYaml(randomWorld(3)), "truth").noise.seed.has_value());

  std::string text = worldYaml(randomWorld(3));
  const std::string key = "  psd_mm: ";
  for (const char* bad : {"-3", "1.5", "seven", "18446744073709551616"}) {
    std::string broken = text;
    broken.insert(broken.find(key), std::string("  seed: ") + bad + "\n");
    try {
      parseWorld(broken, "w.yaml");
      ADD_FAILURE() << bad << " was taken as a seed";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("noise.seed: must be a whole number"), std::string::npos)
          << e.what();
    }
  }
}

TEST(SessionNoise, EachSessionSeatsThePsdAnewOnItsBase) {
  constexpr std::uint64_t kWorld = 5;
  SimulatedArm first(armOn(kWorld)), replay(armOn(kWorld));
  const Eigen::Vector3d at_first = first.world().psd_seated_mm;
  EXPECT_GT(at_first.norm(), 0.0);
  first.reseedNoise(sessionNoiseSeed(kWorld, 1));
  replay.reseedNoise(sessionNoiseSeed(kWorld, 1));
  EXPECT_NE(first.world().psd_seated_mm, at_first);
  EXPECT_EQ(first.world().psd_seated_mm, replay.world().psd_seated_mm);
  // The world's own seed seats it as at the start: a fresh data folder plays what it played.
  first.reseedNoise(kWorld);
  EXPECT_EQ(first.world().psd_seated_mm, at_first);
  // What is where the PSD stands (the world's hash, its file) is not the session's seating.
  EXPECT_EQ(first.world().psd_position_mm, randomWorld(kWorld).psd_position_mm);

  // Over many sessions, as the realistic world says: kPsdSeatSigmaMm per axis.
  double sum2 = 0;
  constexpr int kSessions = 300;
  for (int n = 0; n < kSessions; ++n) {
    first.reseedNoise(sessionNoiseSeed(kWorld, static_cast<std::uint64_t>(n)));
    sum2 += first.world().psd_seated_mm.squaredNorm();
  }
  EXPECT_NEAR(std::sqrt(sum2 / (3 * kSessions)), kPsdSeatSigmaMm, 0.1 * kPsdSeatSigmaMm);

  // The ideal world's PSD never leaves where it stands.
  SimulatedArmOptions ideal = armOn(kWorld);
  ideal.world = randomWorld(kWorld, WorldKind::kIdeal);
  SimulatedArm exact(ideal);
  exact.reseedNoise(sessionNoiseSeed(kWorld, 4));
  EXPECT_EQ(exact.world().psd_seated_mm, Eigen::Vector3d::Zero());
}

TEST(SessionNoise, TheBeamMeetsThePsdWhereItsSeatingPutIt) {
  World w = randomWorld(2);
  // A pose whose beam meets the PSD's plane ahead of the laser.
  std::optional<BeamHit> before;
  Joints q{};
  for (double q2 = -30; q2 <= 30 && !before; q2 += 5)
    for (double q5 = -90; q5 <= 90 && !before; q5 += 15) {
      q = Joints{0, q2, 10, 0, q5, 0};
      before = beamHit(w, q, Joints{}, 0);
    }
  ASSERT_TRUE(before.has_value());
  w.psd_seated_mm = 0.01 * w.psd_rotation.col(0);  // 0.01 mm along the detector's u axis
  const std::optional<BeamHit> after = beamHit(w, q, Joints{}, 0);
  ASSERT_TRUE(after.has_value());
  EXPECT_NEAR(after->spot.u_mm - before->spot.u_mm, -0.01, 1e-9);
  EXPECT_NEAR(after->spot.v_mm - before->spot.v_mm, 0, 1e-9);
}

TEST(SessionNoise, AWorldFileSaysHowThePsdIsSeated) {
  World w = randomWorld(3, WorldKind::kIdeal);
  EXPECT_EQ(worldYaml(w).find("psd_seat_mm"), std::string::npos);
  w.noise.psd_seat_mm = 0.02;
  EXPECT_EQ(parseWorld(worldYaml(w), "truth").noise.psd_seat_mm, 0.02);
  EXPECT_EQ(parseWorld(worldYaml(randomWorld(3)), "truth").noise.psd_seat_mm, kPsdSeatSigmaMm);
  std::string text = worldYaml(w);
  text.replace(text.find("psd_seat_mm: 0.02"), 17, "psd_seat_mm: 3");
  try {
    parseWorld(text, "w.yaml");
    ADD_FAILURE() << "a 3 mm seating was taken";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("noise.psd_seat_mm: must lie within 0..1"),
              std::string::npos)
        << e.what();
  }
}

TEST(ZeroChange, MovesOneJointsTrueZeroOnTopOfTheWorlds) {
  World w = randomWorld(4, WorldKind::kIdeal);
  const Joints before = w.true_offsets_deg;
  applyZeroChange({3, 0.1}, &w);
  for (int j = 0; j < kJointCount; ++j)
    EXPECT_DOUBLE_EQ(w.true_offsets_deg[j], before[j] + (j == 2 ? 0.1 : 0.0)) << "joint " << j + 1;
  applyZeroChange({}, &w);  // none: nothing
  EXPECT_DOUBLE_EQ(w.true_offsets_deg[2], before[2] + 0.1);
}

TEST(Remount, MovesAndTurnsThePsdAndTheLaserButNotWhatTheSessionIsTold) {
  World w = randomWorld(4, WorldKind::kRealistic);
  const World before = w;
  applyRemount({{0.1, -0.2, 0.3}, {0, 0, 1.0}}, {{0.05, 0, 0}, {0, 0.5, 0}}, &w);
  EXPECT_TRUE(w.psd_position_mm.isApprox(before.psd_position_mm + Eigen::Vector3d(0.1, -0.2, 0.3)));
  // Turned by 1 deg about the base's z, on top of its true orientation.
  const Eigen::Matrix3d turn = w.psd_rotation * before.psd_rotation.transpose();
  EXPECT_NEAR(Eigen::AngleAxisd(turn).angle() * 180 / M_PI, 1.0, 1e-9);
  EXPECT_NEAR(std::abs(Eigen::AngleAxisd(turn).axis().z()), 1.0, 1e-9);
  EXPECT_TRUE(w.laser_point_mm.isApprox(before.laser_point_mm + Eigen::Vector3d(0.05, 0, 0)));
  // The beam turned by 0.5 deg about the flange's y: a unit vector v turned by t about a unit
  // axis a keeps cos = cos t + (1 - cos t) (v.a)^2 with itself.
  const double t = 0.5 * M_PI / 180, along = before.laser_direction.normalized().y();
  EXPECT_NEAR(w.laser_direction.dot(before.laser_direction.normalized()),
              std::cos(t) + (1 - std::cos(t)) * along * along, 1e-12);
  EXPECT_NEAR(w.laser_direction.norm(), 1.0, 1e-12);
  EXPECT_TRUE(w.psd_rotation_configured.isApprox(before.psd_rotation_configured));
  EXPECT_TRUE(w.psd_centre_taught_mm.isApprox(before.psd_centre_taught_mm));

  World same = before;
  applyRemount({}, {}, &same);  // none: nothing, bit for bit (the world's hash is the same)
  EXPECT_EQ(worldHash(same), worldHash(before));
  EXPECT_TRUE(same.laser_direction == before.laser_direction);
}

TEST(Remount, BadReMountsAreRefusedWithTheReason) {
  World w = randomWorld(4, WorldKind::kIdeal);
  EXPECT_THROW(applyRemount({{0, 5.5, 0}, {}}, {}, &w), InputError);
  EXPECT_THROW(applyRemount({}, {{}, {0, 0, NAN}}, &w), InputError);
  EXPECT_NE(remountMoveProblem({{0, 0, -7}, {}}).find("within +-5 mm (-7 given)"),
            std::string::npos);
  EXPECT_NE(remountTurnProblem({{}, {2.5, 0, 0}}).find("within +-2 deg (2.5 given)"),
            std::string::npos);
  EXPECT_EQ(remountMoveProblem({{5, -5, 0}, {2, -2, 0}}), "");
  EXPECT_FALSE(Remount{}.any());
  EXPECT_TRUE((Remount{{0, 0, 0}, {0, 0, 0.1}}.any()));
}

TEST(ZeroChange, BadChangesAreRefusedWithTheReason) {
  EXPECT_EQ(zeroChangeProblem({}), "");
  EXPECT_EQ(zeroChangeProblem({5, -2.0}), "");
  EXPECT_NE(zeroChangeProblem({1, 0.1}).find("only the zeros of joints 2..5"), std::string::npos);
  EXPECT_NE(zeroChangeProblem({6, 0.1}).find("joint 6"), std::string::npos);
  EXPECT_NE(zeroChangeProblem({3, 0}).find("non-zero and within +-2 deg"), std::string::npos);
  EXPECT_NE(zeroChangeProblem({3, 2.5}).find("(2.5 given)"), std::string::npos);
  EXPECT_NE(zeroChangeProblem({3, std::nan("")}).find("non-zero"), std::string::npos);
  EXPECT_NE(zeroChangeProblem({0, 0.3}).find("needs its joint"), std::string::npos);
  World w = randomWorld(4, WorldKind::kIdeal);
  const World before = w;
  EXPECT_THROW(applyZeroChange({4, 3.0}, &w), InputError);
  EXPECT_EQ(w.true_offsets_deg, before.true_offsets_deg);
}

}  // namespace
}  // namespace zerocal::sim
