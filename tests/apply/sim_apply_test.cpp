// The simulated controller's motor-side calibration: cal_offset values computed by zerocal apply
// from the true offsets, read and written as on an IRC5, move the simulated arm's true zero onto
// the nominal one; a wrong sign in the configuration doubles the offset, as on a real robot.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "zerocal/apply/motor_calibration.h"
#include "zerocal/apply/transmission_check.h"
#include "zerocal/error.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal {
namespace {

using apply::CalOffsetChange;

Irc5Options clientOptions(std::uint16_t port) {
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = port;
  o.robot = builtinIrb1600();
  o.request_timeout = std::chrono::milliseconds(1000);
  return o;
}

// Computes for joints 2..5 what zerocal apply computes from `delta_deg` with `transmission`, and
// writes it as the online apply does, one MOTOR_CALIB instance at a time.
std::vector<CalOffsetChange> apply(SimController& sim, const std::array<double, 6>& present,
                                   const Joints& delta_deg,
                                   const std::array<double, 6>& transmission) {
  std::vector<CalOffsetChange> changes;
  for (int j = 2; j <= 5; ++j) {
    changes.push_back(apply::calOffsetChange(j, delta_deg[j - 1] * kDegToRad, transmission[j - 1],
                                             present[j - 1]));
    sim.writeCalOffset(j, changes.back().new_rad);
  }
  return changes;
}

TEST(SimulatedMotorCalibration, AppliedValuesMoveTheTrueZeroOnTenWorlds) {
  int seams = 0;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    SimControllerOptions o;
    o.world = randomWorld(seed);
    o.seed = seed;
    SimController sim(o);
    sim.start();
    Irc5Client client(clientOptions(sim.port()));
    client.connect();
    const std::array<double, 6> present = client.readCalOffsets();  // code 41, as zerocald reads
    for (int i = 0; i < 6; ++i) {
      EXPECT_GE(present[i], 0.0);
      EXPECT_LT(present[i], apply::kTwoPi);
      EXPECT_NEAR(present[i], sim.calOffsets()[i], 5e-7);
    }
    const std::vector<CalOffsetChange> changes =
        apply(sim, present, o.world.true_offsets_deg, builtinIrb1600().transmission);
    const std::array<double, 6> read_back = client.readCalOffsets();
    for (const CalOffsetChange& c : changes) {
      const int i = c.joint - 1;
      EXPECT_NEAR(read_back[i], c.new_rad, 1e-6);
      const double remaining = o.world.true_offsets_deg[i] + sim.zeroShiftDeg()[i];
      if (c.crossesSeam()) {
        // The counter still counts the old turn: one motor turn off until it is updated.
        ++seams;
        EXPECT_NEAR(remaining, c.turnErrorRad() * kRadToDeg, 1e-5) << "seed " << seed;
        sim.updateRevolutionCounter(c.joint);
      }
      EXPECT_NEAR(o.world.true_offsets_deg[i] + sim.zeroShiftDeg()[i], 0.0, 1e-5)
          << "seed " << seed << " joint " << c.joint;
    }
    EXPECT_EQ(sim.zeroShiftDeg()[0], 0.0);  // joints 1 and 6 untouched
    EXPECT_EQ(sim.zeroShiftDeg()[5], 0.0);
    // The beam now falls where a world with zero offsets on joints 2..5 puts it.
    World corrected = sim.world();  // the PSD as this session's seating put it
    for (int i = 1; i <= 4; ++i) corrected.true_offsets_deg[i] = 0.0;
    const auto now = sim.beamHitNow();
    const auto expected = beamHit(corrected, sim.commandedJoints(), sim.moveErrorDeg());
    ASSERT_EQ(now.has_value(), expected.has_value());
    if (now) {
      EXPECT_NEAR(now->spot.u_mm, expected->spot.u_mm, 1e-3);
      EXPECT_NEAR(now->spot.v_mm, expected->spot.v_mm, 1e-3);
    }
  }
  // Offsets of up to 1 deg at a transmission of 120 are up to 2 rad on the motor side: some of
  // these ten worlds must have crossed the seam, or the turn handling went untested.
  EXPECT_GT(seams, 0);
}

TEST(SimulatedMotorCalibration, AWrongSignDoublesTheOffsetAWrongRatioLeavesPart) {
  SimControllerOptions o;
  o.world = randomWorld(3);
  o.world.true_offsets_deg = {0.2, 0.3, -0.4, 0.5, -0.6, 0.1};
  o.motor.cal_offset_rad = std::array<double, 6>{3, 3, 3, 3, 3, 3};  // no seam crossing
  SimController sim(o);
  std::array<double, 6> believed = builtinIrb1600().transmission;
  believed[2] = -believed[2];    // joint 3: sign wrong
  believed[3] *= 100.0 / 120.0;  // joint 4: ratio 100 believed, 120... of the placeholder truth
  apply(sim, sim.calOffsets(), o.world.true_offsets_deg, believed);
  const Joints shift = sim.zeroShiftDeg();
  EXPECT_NEAR(o.world.true_offsets_deg[1] + shift[1], 0.0, 1e-5);
  EXPECT_NEAR(o.world.true_offsets_deg[2] + shift[2], 2 * -0.4, 1e-5);
  const double k_true = builtinIrb1600().transmission[3];
  EXPECT_NEAR(o.world.true_offsets_deg[3] + shift[3], 0.5 * (1 - believed[3] / k_true), 1e-5);
}

TEST(SimulatedMotorCalibration, WrittenOverTheLinkTakenAtTheRestart) {
  SimControllerOptions o;
  o.world = randomWorld(2);
  o.motor.cal_offset_rad = std::array<double, 6>{1, 2, 3, 4, 5, 6};
  SimController sim(o);
  sim.start();
  Irc5Client client(clientOptions(sim.port()));
  client.connect();
  client.writeCalOffset(3, 3.5);
  // The configuration holds it at once (ReadCfgData); the motion system only after a restart.
  EXPECT_NEAR(client.readCalOffsets()[2], 3.5, 1e-6);
  EXPECT_EQ(sim.zeroShiftDeg(), Joints{});
  EXPECT_THROW(client.writeCalOffset(3, 6.3), BadMessageError);  // beyond one motor turn
  EXPECT_THROW(client.writeCalOffset(7, 1.0), BadMessageError);  // no such joint
  const long connections = sim.connectionCount();
  client.restartController();  // the controller drops the link; the client reconnects
  EXPECT_GT(sim.connectionCount(), connections);
  EXPECT_NEAR(sim.zeroShiftDeg()[2], 0.5 / builtinIrb1600().transmission[2] * kRadToDeg, 1e-9);
  EXPECT_NEAR(sim.calOffsets()[2], 3.5, 1e-6);
  EXPECT_NEAR(client.readCalOffsets()[2], 3.5, 1e-6);
  EXPECT_EQ(sim.zeroShiftDeg()[1], 0.0);
}

// A restart costs what a warm start costs (restart_s of simulated time, pace x that of wall time),
// and meanwhile the controller refuses connections; the client waits for it, up to its
// restart_timeout.
TEST(SimulatedMotorCalibration, ARestartTakesAWarmStartsTimeRefusingConnectionsMeanwhile) {
  using namespace std::chrono;
  SimControllerOptions o;
  o.world = randomWorld(2);
  o.restart_s = 30;
  o.pace = 0.01;  // 0.3 s of wall time
  SimController sim(o);
  sim.start();
  Irc5Client client(clientOptions(sim.port()));
  client.connect();
  const double before_s = sim.simTimeS();
  const auto asked = steady_clock::now();
  client.rawRequest("46 #", 0, milliseconds(1000));
  Irc5Client probe(clientOptions(sim.port()));
  for (int i = 0; i < 100 && sim.restartCount() == 0; ++i) std::this_thread::sleep_for(1ms);
  EXPECT_THROW(probe.connect(), ConnectionError);  // refused: the server is not back
  EXPECT_EQ(sim.simTimeS() - before_s, 30.0);
  bool back = false;
  while (!back && steady_clock::now() - asked < 5s) {
    try {
      probe.connect();
      back = true;
    } catch (const ConnectionError&) {
      std::this_thread::sleep_for(5ms);
    }
  }
  ASSERT_TRUE(back);
  const auto down = steady_clock::now() - asked;
  EXPECT_GE(down, 290ms);
  EXPECT_LT(down, 3s);
  probe.close();

  // restartController() waits for it; with a restart_timeout shorter than the restart it gives up.
  client.connect();
  const auto t0 = steady_clock::now();
  client.restartController();
  EXPECT_GE(steady_clock::now() - t0, 290ms);
  EXPECT_TRUE(client.connected());
  EXPECT_EQ(sim.restartCount(), 2);
  Irc5Options impatient = clientOptions(sim.port());
  impatient.restart_timeout = milliseconds(100);
  Irc5Client hurried(impatient);
  hurried.connect();
  client.close();
  EXPECT_THROW(hurried.restartController(), TimeoutError);
}

TEST(SimulatedMotorCalibration, RefusesValuesNoControllerHolds) {
  SimControllerOptions o;
  o.world = randomWorld(1);
  o.world.robot.transmission[1] = 0;  // joint 2's transmission unknown
  SimController sim(o);
  const std::array<double, 6> before = sim.calOffsets();
  EXPECT_THROW(sim.writeCalOffset(3, 7.0), ConfigError);
  EXPECT_THROW(sim.writeCalOffset(3, -0.1), ConfigError);
  EXPECT_THROW(sim.writeCalOffset(2, 1.0), ConfigError);
  EXPECT_THROW(sim.writeCalOffset(7, 1.0), ConfigError);
  EXPECT_EQ(sim.zeroShiftDeg(), Joints{});
  EXPECT_EQ(sim.calOffsets(), before);
  SimControllerOptions bad = o;
  bad.motor.cal_offset_rad = std::array<double, 6>{0, 0, -1, 0, 0, 0};
  EXPECT_THROW(SimController{bad}, ConfigError);
}

}  // namespace
}  // namespace zerocal

namespace zerocal {
namespace {

// The transmission measured through the real client (which is both the link that moves and the
// calibration that reads the motors) against the simulated controller, whose motors turn by the
// arm's true transmission.
Irc5Options withMargin(Irc5Options o) {
  o.limit_margin_deg = 1.0;
  return o;
}

struct MeasuredCell {
  explicit MeasuredCell(SimControllerOptions o)
      : sim(std::move(o)), client(withMargin(clientOptions(sim.port()))) {
    sim.start();
    client.connect();
  }
  SimController sim;
  Irc5Client client;
};

SimControllerOptions measuredOptions() {
  SimControllerOptions o;
  o.world = randomWorld(6, WorldKind::kIdeal);
  o.start_joints = {10, 20, -30, 40, 50, 60};
  return o;
}

TEST(TransmissionCheck, TheRightTransmissionIsMeasuredAndTheRobotMovedBack) {
  SimControllerOptions o = measuredOptions();
  // Motor angles close below a full turn: the step carries some of them over the wrap.
  o.motor.cal_offset_rad = std::array<double, 6>{6.2, 6.2, 6.2, 6.2, 6.2, 6.2};
  MeasuredCell cell(o);
  const Robot robot = builtinIrb1600();
  for (int j = 2; j <= 5; ++j) {
    const Joints before = cell.sim.commandedJoints();
    const long moves = cell.sim.motionTotals().moves;
    const apply::TransmissionMeasurement m =
        apply::measureTransmission(cell.client, cell.client, robot, j);
    EXPECT_TRUE(m.agrees) << m.message;
    EXPECT_NEAR(m.measured, robot.transmission[j - 1], 1e-3 * std::abs(robot.transmission[j - 1]))
        << "joint " << j;
    EXPECT_NEAR(std::abs(m.joint_step_deg), 0.5, 1e-4);
    EXPECT_EQ(cell.sim.commandedJoints(), before) << "joint " << j << " not moved back";
    EXPECT_EQ(cell.sim.motionTotals().moves - moves, 2);
  }
}

TEST(TransmissionCheck, AWrongSignOrRatioInTheRobotFileIsNamedWithBothRatios) {
  MeasuredCell cell(measuredOptions());
  Robot robot = builtinIrb1600();
  robot.transmission[2] = -robot.transmission[2];  // joint 3: the sign wrong
  robot.transmission[3] = 100;                     // joint 4: the arm's is +80
  const apply::TransmissionMeasurement sign =
      apply::measureTransmission(cell.client, cell.client, robot, 3);
  EXPECT_FALSE(sign.agrees);
  EXPECT_NEAR(sign.measured, 120, 0.1);
  EXPECT_NE(sign.message.find("joint 3: the robot file's transmission is -120, the cell measured "
                              "+120.00"),
            std::string::npos)
      << sign.message;
  EXPECT_NE(sign.message.find("the sign is wrong"), std::string::npos) << sign.message;
  const apply::TransmissionMeasurement ratio =
      apply::measureTransmission(cell.client, cell.client, robot, 4);
  EXPECT_FALSE(ratio.agrees);
  EXPECT_NEAR(ratio.measured, 80, 0.1);
  EXPECT_NE(ratio.message.find("joint 4: the robot file's transmission is +100, the cell measured "
                               "+80.00"),
            std::string::npos)
      << ratio.message;
  EXPECT_EQ(cell.sim.commandedJoints(), measuredOptions().start_joints);
  // The arm's own transmission with its sign reversed (a motor mounted the other way): measured
  // as such, so a robot file that has it right agrees.
  SimControllerOptions reversed = measuredOptions();
  reversed.motor.transmission = builtinIrb1600().transmission;
  (*reversed.motor.transmission)[4] = -80;
  MeasuredCell other(reversed);
  Robot right = builtinIrb1600();
  right.transmission[4] = -80;
  const apply::TransmissionMeasurement m =
      apply::measureTransmission(other.client, other.client, right, 5);
  EXPECT_TRUE(m.agrees) << m.message;
  EXPECT_NEAR(m.measured, -80, 0.1);
}

TEST(TransmissionCheck, StepsAwayFromTheNearerLimitAndMovesNothingWhenTheStepIsRefused) {
  SimControllerOptions o = measuredOptions();
  const Robot robot = builtinIrb1600();
  o.start_joints[1] = robot.limits[1].upper_deg - 1.2;  // joint 2 0.2 deg outside the margin
  MeasuredCell near(o);
  const apply::TransmissionMeasurement m =
      apply::measureTransmission(near.client, near.client, robot, 2);
  EXPECT_TRUE(m.agrees) << m.message;
  EXPECT_LT(m.joint_step_deg, 0);  // towards the middle, not over the limit
  // Joint 3 inside the 1 deg margin: its step towards the middle still ends within it, and the
  // link refuses it before anything moves, as every move.
  o = measuredOptions();
  o.start_joints[2] = robot.limits[2].lower_deg + 0.3;
  MeasuredCell cell(o);
  const long moves = cell.sim.motionTotals().moves;
  EXPECT_THROW(apply::measureTransmission(cell.client, cell.client, robot, 3), RequestRefusedError);
  EXPECT_EQ(cell.sim.motionTotals().moves, moves);
  for (int i = 0; i < kJointCount; ++i)
    EXPECT_NEAR(cell.sim.commandedJoints()[i], o.start_joints[i], 1e-4);
}

}  // namespace
}  // namespace zerocal
