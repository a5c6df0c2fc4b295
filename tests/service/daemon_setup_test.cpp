// The daemon's parts from its configuration: each section reaches its component whole.
#include "zerocal/service/daemon_setup.h"

#include <gtest/gtest.h>

#include "zerocal/irc5/irc5_kind.h"
#include "zerocal/irc5/motion_time.h"
#include "zerocal/model/builtin.h"
#include "zerocal/service/cell_factory.h"

namespace zerocal::service {
namespace {

Irc5Options& irc5Of(DaemonConfig& config) {
  return config.controller.sections.get<irc5::Irc5Settings>("irc5")->options;
}

// The servo section is the servo's options; the controller's margin and the session's noise and
// required accuracy join them for the run.
TEST(DaemonSetup, TheRunTakesTheServoSectionWholeAndTheSessionsAccuracy) {
  DaemonConfig config;
  config.servo.stop = servo::ServoStop::kCentre;
  config.servo.tolerance_um = 1.5;
  config.servo.gain = 0.7;
  config.servo.damping_mm = 0.01;
  config.servo.search_step_mm = 3.0;
  irc5Of(config).limit_margin_deg = 2.5;
  config.session.noise_mm = 0.03;
  config.session.required_accuracy_deg = 0.02;
  const RunSettings run = runSettingsOf(config);
  EXPECT_EQ(run.servo.stop, servo::ServoStop::kCentre);
  EXPECT_EQ(run.servo.tolerance_um, 1.5);
  EXPECT_EQ(run.servo.gain, 0.7);
  EXPECT_EQ(run.servo.damping_mm, 0.01);
  EXPECT_EQ(run.servo.search_step_mm, 3.0);
  EXPECT_EQ(run.servo.limit_margin_deg, 2.5);
  EXPECT_EQ(run.solve.noise_mm, 0.03);
  EXPECT_EQ(run.solve.required_accuracy_deg, 0.02);
  EXPECT_TRUE(run.servo.validate().empty()) << run.servo.validate();
}

// Every solve counts what the robot model admits: the shipped robot file's tolerances on the
// realistic simulated cell and on the hardware cell, nothing in the seed's ideal world (its arm
// is the robot file exactly).
TEST(DaemonSetup, TheRobotModelsTolerancesCountExceptInTheIdealWorld) {
  DaemonConfig config;
  config.backend.kind = BackendKind::kSim;
  const auto counted = [&] { return makeBackend(config)->knowledge().cell.robot.tolerance; };
  EXPECT_EQ(counted().length_mm, 0.1);
  EXPECT_EQ(counted().angle_deg, 0.01);
  EXPECT_EQ(counted().sag_deg[0], 0.007);
  EXPECT_EQ(counted().sag_deg[1], 0.0042);
  config.backend.sim_ideal_world = true;
  EXPECT_FALSE(counted().counted());
  EXPECT_EQ(robotOf(config.controller).tolerance.length_mm, 0.1);
}

// One set of defaults: the configuration's are the servo's and the solver's.
TEST(DaemonSetup, TheDefaultsAreTheComponentsOwn) {
  const RunSettings run = runSettingsOf(DaemonConfig{});
  const servo::ServoOptions servo;
  EXPECT_EQ(run.servo.stop, servo.stop);
  EXPECT_EQ(run.servo.settle_s, servo.settle_s);
  EXPECT_EQ(run.servo.timeout_s, servo.timeout_s);
  EXPECT_EQ(run.solve.required_accuracy_deg, SolveOptions{}.required_accuracy_deg);
}

// The plan's poses are ordered by what a move between them costs the controller at the
// configured speeds: the same motion model the simulated controller charges.
TEST(DaemonSetup, PlansAreOrderedByTheControllersMotionAtItsSpeeds) {
  DaemonConfig config;
  const Robot robot = builtinIrb1600();
  const Joints from{0, 0, 0, 0, 30, 0}, to{20, 25, -10, 40, 60, -30};
  const auto fast = managerSettingsOf(config).travel_s;
  ASSERT_TRUE(fast);
  EXPECT_DOUBLE_EQ(fast(robot, from, to),
                   irc5::jointMoveTime(robot, from, to, irc5Of(config).speed_tcp_mm_s,
                                       irc5Of(config).speed_ori_deg_s, irc5::MotionCosts{})
                       .motion_s);
  irc5Of(config).speed_tcp_mm_s /= 4;
  irc5Of(config).speed_ori_deg_s /= 4;
  EXPECT_GT(managerSettingsOf(config).travel_s(robot, from, to), 2 * fast(robot, from, to));
}

}  // namespace
}  // namespace zerocal::service
