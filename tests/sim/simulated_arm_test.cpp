// The simulated arm alone, in-process: no socket, no controller protocol.
#include "zerocal/sim/simulated_arm.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <thread>

#include "stored_plan.h"
#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/sim/psd_model.h"

namespace zerocal::sim {
namespace {

// A motion model simple enough to predict by hand: the joint that moves most at the orientation
// speed, a fixed 0.25 s for the ramps.
MotionModel handModel() {
  MotionModel m;
  m.cruise_s = [](const Robot&, const Joints& from, const Joints& to, const MoveSpeed& speed) {
    double largest = 0;
    for (int i = 0; i < kJointCount; ++i) largest = std::max(largest, std::abs(to[i] - from[i]));
    return largest / speed.ori_deg_s;
  };
  m.profile_s = [](double cruise_s, double) { return cruise_s + 0.25; };
  m.overhead_s = 0.3;
  m.settle_s = 0.1;
  return m;
}

SimulatedArmOptions armOptions() {
  SimulatedArmOptions o;
  o.world = randomWorld(11, WorldKind::kIdeal);
  o.world.noise.repeatability_deg = 0;  // exact read-backs
  o.motion = handModel();
  o.restart_s = 20;
  o.motor.cal_offset_rad = std::array<double, kJointCount>{1, 1, 1, 1, 1, 1};
  o.identity = RobotInfo{"SIM-0001", "1.0", "a test arm"};
  return o;
}

TEST(SimulatedArm, AJointMoveCostsWhatTheModelSays) {
  SimulatedArm arm(armOptions());
  arm.setSpeed({100, 50});
  const MoveResult r = arm.moveJoints({10, 0, 0, 0, 30, 0});
  ASSERT_TRUE(r.moved());
  // 10 deg of joint 1 at 50 deg/s, the ramps, the overhead, the settling.
  EXPECT_DOUBLE_EQ(r.cost.motion_s, 0.2 + 0.25);
  EXPECT_DOUBLE_EQ(r.cost.overhead_s, 0.3);
  EXPECT_DOUBLE_EQ(r.cost.settle_s, 0.1);
  EXPECT_DOUBLE_EQ(arm.timeS(), 0.85);
  EXPECT_EQ(arm.joints(), (Joints{10, 0, 0, 0, 30, 0}));
  const MotionTotals totals = arm.motionTotals();
  EXPECT_EQ(totals.moves, 1);
  EXPECT_EQ(totals.search_moves, 0);
  EXPECT_DOUBLE_EQ(totals.motion_s, 0.45);
}

TEST(SimulatedArm, ALinearMoveCostsItsStraightPathAtTheTcpSpeed) {
  SimulatedArm arm(armOptions());
  arm.setSpeed({100, 50});
  ASSERT_TRUE(arm.moveJoints({0, 10, 10, 0, 30, 0}).moved());
  const double t0 = arm.timeS();
  TcpPose target = arm.toolPose();
  target.xyz_mm[0] += 20;
  const MoveResult r = arm.moveLinear(target);
  ASSERT_TRUE(r.moved());
  EXPECT_NEAR(r.cost.motion_s, 20.0 / 100 + 0.25, 1e-9);  // 20 mm at 100 mm/s, no turn
  EXPECT_NEAR(arm.timeS() - t0, r.cost.total(), 1e-12);
  const TcpPose now = arm.toolPose();
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(now.xyz_mm[i], target.xyz_mm[i], 1e-6);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(now.quat_wxyz[i], target.quat_wxyz[i], 1e-9);
}

TEST(SimulatedArm, AMoveBeyondTheLimitsIsRefusedAndDoesNotMove) {
  SimulatedArm arm(armOptions());
  const Joints home = arm.joints();
  MoveResult r = arm.moveJoints({0, 130, 0, 0, 30, 0});  // joint 2 stops at 120 deg
  EXPECT_EQ(r.refusal, MoveRefusal::kOutOfLimits);
  EXPECT_EQ(r.cost.total(), 0.0);
  TcpPose far = arm.toolPose();
  far.xyz_mm[0] += 5000;  // out of reach
  r = arm.moveLinear(far);
  EXPECT_EQ(r.refusal, MoveRefusal::kUnreachable);
  SpotSearch wild;
  wild.centre_deg = home;
  wild.per_u_mm[0] = 10;  // 10 deg of joint 1 per mm: beyond its range within the spiral
  r = arm.searchRun(wild, {0, 30, 100});
  EXPECT_EQ(r.refusal, MoveRefusal::kOutOfLimits);
  EXPECT_EQ(arm.joints(), home);
  EXPECT_EQ(arm.timeS(), 0.0);
  EXPECT_EQ(arm.motionTotals().moves, 0);
}

TEST(SimulatedArm, SinglePrecisionStoresJointsAsFloats) {
  SimulatedArmOptions o = armOptions();
  o.single_precision = true;
  SimulatedArm arm(o);
  ASSERT_TRUE(arm.moveJoints({0.1, 0, 0, 0, 30, 0}).moved());
  EXPECT_EQ(arm.joints()[0], static_cast<double>(0.1f));
}

// The spot on the PSD (mm) for joints q of the world's true arm.
Eigen::Vector2d spotAt(const World& w, const Joints& q) {
  const std::optional<BeamHit> hit = beamHit(w, q);
  EXPECT_TRUE(hit);
  return hit ? Eigen::Vector2d(hit->spot.u_mm, hit->spot.v_mm) : Eigen::Vector2d::Zero();
}

// A spiral around the joints that put the spot `start_mm` from the detector's centre, mapped by
// the true arm's image Jacobian at q (its pseudo-inverse), as a servo would map it.
SpotSearch spiralOffCentre(const World& w, const Joints& q, const Eigen::Vector2d& start_mm) {
  Eigen::Matrix<double, 2, kJointCount> jac;
  const Eigen::Vector2d s0 = spotAt(w, q);
  for (int j = 0; j < kJointCount; ++j) {
    Joints qj = q;
    qj[j] += 1e-4;
    jac.col(j) = (spotAt(w, qj) - s0) / 1e-4;
  }
  const Eigen::Matrix<double, kJointCount, 2> pinv =
      jac.transpose() * (jac * jac.transpose()).inverse();
  SpotSearch spiral;
  const Eigen::Matrix<double, kJointCount, 1> dq = pinv * (start_mm - s0);
  for (int i = 0; i < kJointCount; ++i) {
    spiral.centre_deg[i] = q[i] + dq[i];
    spiral.per_u_mm[i] = pinv(i, 0);
    spiral.per_v_mm[i] = pinv(i, 1);
  }
  return spiral;
}

// A run latches the joints where the light rose (with no latency: at the edge of the lit disk)
// and stops soon after; a run that never meets the light goes to its end and latches nothing.
TEST(SimulatedArm, ASearchLatchesTheJointsWhereTheLightRose) {
  SimulatedArmOptions o = armOptions();
  o.search.latency_min_s = o.search.latency_max_s = 0;  // latched where the light rose
  SimulatedArm arm(o);
  const World& w = arm.world();
  const Joints planned = testing::storedPlan("ideal-11")[0].q_deg;
  const SpotSearch spiral = spiralOffCentre(w, planned, {15, 0});
  ASSERT_TRUE(arm.moveJoints(spiral.centre_deg).moved());
  ASSERT_GT(spotAt(w, arm.joints()).norm(), 12.0) << "the search must start in the dark";

  const MoveResult small = arm.searchRun(spiral, {0, 4, 100});
  ASSERT_TRUE(small.moved());
  EXPECT_FALSE(small.latched_deg);
  Joints last{};
  forEachSearchWaypoint(spiral, SearchRun{0, 4, 100}, [&](const Joints& q) {
    last = q;
    return true;
  });
  EXPECT_EQ(arm.joints(), last);

  ASSERT_TRUE(arm.moveJoints(spiral.centre_deg).moved());
  const double t0 = arm.timeS();
  const MoveResult r = arm.searchRun(spiral, {0, 30, 100});
  ASSERT_TRUE(r.moved());
  ASSERT_TRUE(r.latched_deg);
  EXPECT_NEAR(arm.timeS() - t0, r.cost.total(), 1e-12);
  EXPECT_EQ(arm.motionTotals().search_moves, 2);
  // Where the comparator sees the light rise: the detector's SUM reaches the threshold at the
  // rim of the lit disk, about 5.2..5.7 mm from its centre in the latched spot's direction.
  const Eigen::Vector2d latched = spotAt(w, *r.latched_deg);
  const Eigen::Vector2d towards = latched.normalized();
  const PsdModel detector(o.search.psd);
  double inside = 0, outside = 10;
  for (int k = 0; k < 60; ++k) {
    const double r_mm = (inside + outside) / 2;
    const PsdSpot at{r_mm * towards.x(), r_mm * towards.y()};
    (detector.ideal(at).sum > o.search.threshold_v ? inside : outside) = r_mm;
  }
  EXPECT_NEAR(latched.norm(), inside, 0.2);
  // Stopped a waypoint or two after the latch, far before the spiral's end at 30 mm.
  EXPECT_LT((spotAt(w, arm.joints()) - spotAt(w, *r.latched_deg)).norm(), 16.0);
}

TEST(SimulatedArm, WithoutTheLightSignalASearchIsRefused) {
  SimulatedArmOptions o = armOptions();
  o.search.wired = false;
  SimulatedArm arm(o);
  EXPECT_FALSE(arm.searchSignalWired());
  SpotSearch spiral;
  spiral.centre_deg = arm.joints();
  EXPECT_EQ(arm.searchRun(spiral, {0, 4, 100}).refusal, MoveRefusal::kNoSearchSignal);
}

// A written cal_offset waits in the configuration until the restart, which takes it (the joint's
// true zero moves by the change over the transmission) and costs restart_s of the clock.
TEST(SimulatedArm, MotorCalibrationIsWrittenTakenAtTheRestartAndReadBack) {
  SimulatedArm arm(armOptions());
  const double k3 = arm.world().robot.transmission[2];
  ASSERT_NE(k3, 0);
  EXPECT_EQ(arm.configureCalOffset(3, 1.5), CalOffsetRefusal::kNone);
  EXPECT_EQ(arm.calOffsets()[2], 1.0);
  EXPECT_EQ(arm.configuredCalOffsets()[2], 1.5);
  EXPECT_EQ(arm.zeroShiftDeg(), Joints{});

  EXPECT_EQ(arm.restart(), 20.0);
  EXPECT_EQ(arm.timeS(), 20.0);
  EXPECT_EQ(arm.restartCount(), 1);
  EXPECT_EQ(arm.calOffsets()[2], 1.5);
  EXPECT_EQ(arm.configuredCalOffsets(), arm.calOffsets());
  EXPECT_DOUBLE_EQ(arm.zeroShiftDeg()[2], 0.5 / k3 * kRadToDeg);
  // The motor behind the joint: cal_offset + k q, within one motor turn.
  const double q3 = arm.joints()[2] * kDegToRad;
  const double turns = 1.5 + k3 * q3;
  EXPECT_NEAR(arm.motorAnglesRad()[2], turns - 2 * kPi * std::floor(turns / (2 * kPi)), 1e-12);
  EXPECT_NEAR(arm.motorAnglesRad()[0], 1.0, 1e-12);  // joint 1 at 0 deg
}

TEST(SimulatedArm, CalOffsetsNoControllerHoldsAreRefused) {
  SimulatedArmOptions o = armOptions();
  o.world.robot.transmission[1] = 0;  // joint 2's transmission unknown
  SimulatedArm arm(o);
  EXPECT_EQ(arm.configureCalOffset(7, 1.0), CalOffsetRefusal::kNoSuchJoint);
  EXPECT_EQ(arm.configureCalOffset(3, 7.0), CalOffsetRefusal::kOutOfRange);
  EXPECT_EQ(arm.configureCalOffset(3, -0.1), CalOffsetRefusal::kOutOfRange);
  EXPECT_EQ(arm.configureCalOffset(2, 1.0), CalOffsetRefusal::kTransmissionUnknown);
  EXPECT_THROW(arm.takeCalOffset(2, 1.0), ConfigError);
  EXPECT_THROW(arm.takeCalOffset(3, 7.0), ConfigError);
  arm.restart();
  EXPECT_EQ(arm.calOffsets(), (std::array<double, kJointCount>{1, 1, 1, 1, 1, 1}));
}

// A cal_offset change of almost a motor turn moves the zero by almost a turn of the motor; the
// revolution counter's update takes the whole turn away and leaves the rest.
TEST(SimulatedArm, TheRevolutionCounterUpdateRemovesWholeMotorTurns) {
  SimulatedArmOptions o = armOptions();
  o.motor.cal_offset_rad =
      std::array<double, kJointCount>{0.005, 0.005, 0.005, 0.005, 0.005, 0.005};
  SimulatedArm arm(o);
  const double k4 = arm.world().robot.transmission[3];
  arm.takeCalOffset(4, 2 * kPi - 0.005);
  EXPECT_NEAR(arm.zeroShiftDeg()[3], (2 * kPi - 0.01) / k4 * kRadToDeg, 1e-12);
  arm.updateRevolutionCounter(4);
  EXPECT_NEAR(arm.zeroShiftDeg()[3], -0.01 / k4 * kRadToDeg, 1e-12);
  EXPECT_THROW(arm.updateRevolutionCounter(0), ConfigError);
}

// The clock is the arm's own: moves and restarts advance it by their cost, nothing else does.
TEST(SimulatedArm, TheClockAdvancesByTheMovesAndRestartsOnly) {
  SimulatedArm arm(armOptions());
  double expected = 0;
  for (const Joints& q : {Joints{5, 0, 0, 0, 30, 0}, Joints{5, 5, 0, 0, 30, 0}}) {
    expected += arm.moveJoints(q).cost.total();
    EXPECT_DOUBLE_EQ(arm.timeS(), expected);
  }
  arm.setSpeed({200, 100});
  (void)arm.joints();
  (void)arm.beamHitNow();
  EXPECT_DOUBLE_EQ(arm.timeS(), expected);
  expected += arm.restart();
  EXPECT_DOUBLE_EQ(arm.timeS(), expected);
}

// A warm arm (warm_s: the controller has been working that long) starts its clock there, and its
// links have grown by what ThermalDrift says: the beam meets the PSD where the flange, displaced
// by the growth of the arm (every length scaled, the orientations not), puts it.
TEST(SimulatedArm, AWarmArmHasGrownByWhatItsThermalDriftSays) {
  SimulatedArmOptions cold = armOptions();
  cold.world = randomWorld(11);  // realistic: link errors, sag and warming
  cold.world.noise.repeatability_deg = 0;
  cold.world.gross = GrossErrors{};
  SimulatedArmOptions warm = cold;
  warm.warm_s = 7200;
  SimulatedArm cold_arm(cold), warm_arm(warm);
  EXPECT_EQ(cold_arm.timeS(), 0.0);
  EXPECT_EQ(warm_arm.timeS(), 7200.0);
  // A pose that puts the beam on the PSD of this world.
  const Joints q{0, 30, 10, 0, 40, 0};
  const double cost = cold_arm.moveJoints(q).cost.total();
  ASSERT_EQ(warm_arm.moveJoints(q).cost.total(), cost);
  EXPECT_DOUBLE_EQ(warm_arm.timeS() - cold_arm.timeS(), 7200.0);

  const ThermalDrift& t = cold.world.thermal;
  ASSERT_GT(t.rise_k, 0);
  const auto growth = [&](double time_s) {
    return t.expansion_per_k * t.rise_k * (1 - std::exp(-time_s / t.time_constant_s));
  };
  // Every length scales by 1 + growth, so the flange (and the laser on it) moves by the ratio of
  // the two scales, less one, times its position from the base.
  const Eigen::Vector3d flange = trueFlangePositionMm(cold.world, q, cold_arm.timeS());
  const Eigen::Vector3d moved =
      ((1 + growth(warm_arm.timeS())) / (1 + growth(cold_arm.timeS())) - 1) * flange;
  EXPECT_GT(moved.norm(), 0.02);  // tens of micrometres at least: measurable on the PSD
  EXPECT_NEAR((trueFlangePositionMm(cold.world, q, warm_arm.timeS()) - flange - moved).norm(), 0,
              1e-9);
  // On the PSD: the beam is parallel to the cold one, shifted by `moved` along the plane.
  const Eigen::Matrix3d& r = cold.world.psd_rotation;
  const Eigen::Vector3d n = r.col(2);
  const Frame<double> f = flangePoseDeg(cold.world.robot, q, cold.world.true_offsets_deg);
  const Eigen::Vector3d d = (f.R * cold.world.laser_direction).normalized();
  const Eigen::Vector3d on_plane = r.transpose() * (moved - d * n.dot(moved) / n.dot(d));
  const std::optional<BeamHit> a = cold_arm.beamHitNow(), b = warm_arm.beamHitNow();
  ASSERT_TRUE(a && b);
  const Eigen::Vector2d shift(b->spot.u_mm - a->spot.u_mm, b->spot.v_mm - a->spot.v_mm);
  // Within 5%: the beam's direction is the nominal arm's here, the true one's differs by the
  // link twists and the sag, a fraction of a degree.
  EXPECT_NEAR((shift - on_plane.head<2>()).norm(), 0, 0.05 * on_plane.head<2>().norm())
      << "spot moved by (" << shift.transpose() << ") mm, the growth predicts ("
      << on_plane.head<2>().transpose() << ")";
  EXPECT_GT(shift.norm(), 0.01);
}

// A server's I/O thread moves the arm while another thread reads it: every reading is a state
// the arm was in (a target reached, a clock that only grows).
TEST(SimulatedArm, ReadersSeeWholeMovesWhileAnotherThreadMoves) {
  SimulatedArm arm(armOptions());
  const Joints a{5, 0, 0, 0, 30, 0}, b{-5, 10, 0, 0, 30, 0};
  std::thread mover([&] {
    for (int i = 0; i < 200; ++i) arm.moveJoints(i % 2 == 0 ? a : b);
  });
  double last_s = 0;
  while (arm.motionTotals().moves < 200) {
    const Joints q = arm.joints();
    EXPECT_TRUE(q == a || q == b || q == (Joints{0, 0, 0, 0, 30, 0}));
    const double now_s = arm.timeS();
    EXPECT_GE(now_s, last_s);
    last_s = now_s;
  }
  mover.join();
  EXPECT_EQ(arm.joints(), b);
}

TEST(SimulatedArm, OptionsItCannotRunWithAreAConfigError) {
  SimulatedArmOptions o = armOptions();
  o.motion = MotionModel{};  // no timing model
  EXPECT_THROW(SimulatedArm{o}, ConfigError);
  o = armOptions();
  o.start_joints[1] = 130;
  EXPECT_THROW(SimulatedArm{o}, ConfigError);
  o = armOptions();
  o.motor.cal_offset_rad = std::array<double, kJointCount>{0, 0, -1, 0, 0, 0};
  EXPECT_THROW(SimulatedArm{o}, ConfigError);
  o = armOptions();
  o.restart_s = -1;
  EXPECT_THROW(SimulatedArm{o}, ConfigError);
  for (const double warm_s : {-1.0, kMaxWarmS + 1, std::nan("")}) {
    o = armOptions();
    o.warm_s = warm_s;
    try {
      SimulatedArm arm(o);
      ADD_FAILURE() << "warm_s " << warm_s << " taken";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("warm_s must be within 0..604800 s"), std::string::npos)
          << e.what();
    }
  }
}

TEST(SimulatedArm, ItsIdentityIsData) {
  SimulatedArm arm(armOptions());
  EXPECT_EQ(arm.identity().serial, "SIM-0001");
  EXPECT_EQ(arm.identity().software_version, "1.0");
  EXPECT_EQ(arm.identity().robot_type, "a test arm");
}

}  // namespace
}  // namespace zerocal::sim
