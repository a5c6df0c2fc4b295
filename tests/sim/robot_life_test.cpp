// The simulated cell plays one robot's life, as the daemon builds it from its configuration: each
// session in a data folder draws its own noise on the same arm, and a motor replacement (one
// joint's zero changed) shows in the truth and in what a calibration identifies.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "exact_robot.h"
#include "stored_plan_request.h"
#include "temp_dir.h"
#include "zerocal/error.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/sim_backend.h"
#include "zerocal/sim/world.h"

namespace zerocal {
namespace {

constexpr std::uint64_t kSeed = 7;  // the stored plan ideal-7 is this world's

DaemonConfig idealWorld(const std::string& data_dir) {
  DaemonConfig c;
  c.backend.kind = BackendKind::kSim;
  c.backend.sim_seed = kSeed;
  c.backend.sim_ideal_world = true;
  c.session.data_dir = data_dir;
  return c;
}

struct Session {
  ResultFile result;
  World truth;  // the session's truth-world.yaml
};

// One session as `zerocald --sim --once` runs it: a backend and a manager of their own.
Session runOnce(const DaemonConfig& config) {
  const std::unique_ptr<CellBackend> backend = service::makeBackend(config);
  service::ManagerSettings settings = service::managerSettingsOf(config);
  settings.write_reports = nullptr;
  service::SessionManager manager(*backend, settings);
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-7"));
  const service::SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, service::SessionState::kDone) << end.message;
  Session s{manager.result(id), {}};
  if (s.result.truth && !s.result.truth->world_file.empty())
    s.truth = loadWorld(config.session.data_dir + "/" + id + "/" + s.result.truth->world_file);
  return s;
}

TEST(RobotLife, TwoSessionsInOneDataFolderDrawTheirOwnNoiseOnTheSameArm) {
  const testing::TempDir dir("zerocal-life");
  const DaemonConfig config = idealWorld(dir.path + "/sessions");
  const Session first = runOnce(config);
  const Session second = runOnce(config);
  ASSERT_TRUE(first.result.truth && second.result.truth);
  ASSERT_TRUE(first.result.truth->noise_seed && second.result.truth->noise_seed);
  // The first session in a fresh folder draws from the world's seed, as every session did.
  EXPECT_EQ(*first.result.truth->noise_seed, kSeed);
  EXPECT_EQ(*second.result.truth->noise_seed, sessionNoiseSeed(kSeed, 1));
  EXPECT_EQ(first.truth.noise.seed, first.result.truth->noise_seed);
  EXPECT_EQ(second.truth.noise.seed, second.result.truth->noise_seed);
  // The same arm: its whole world, and the true offsets.
  EXPECT_EQ(worldHash(first.truth), worldHash(second.truth));
  EXPECT_EQ(first.result.truth->offsets_deg, second.result.truth->offsets_deg);
  // Other noise: the identified offsets differ (by about their sigma, not more).
  double largest = 0;
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& a = first.result.report.parameters[k];
    const ParameterEstimate& b = second.result.report.parameters[k];
    EXPECT_NE(a.value, b.value) << unknownName(k);
    EXPECT_LT(std::abs(a.value - b.value), 5 * std::hypot(a.sigma, b.sigma)) << unknownName(k);
    largest = std::max(largest, std::abs(a.value - b.value));
  }
  EXPECT_GT(largest, 1e-6);

  // A third session replays the second from its truth file (the file names the noise seed).
  const testing::TempDir elsewhere("zerocal-life");
  DaemonConfig replay = idealWorld(elsewhere.path + "/sessions");
  replay.backend.sim_seed.reset();
  replay.backend.sim_world = elsewhere.path + "/second.yaml";
  // A world file's arm may have link errors, so the solve counts them; this one has none, as the
  // seed's ideal world: solved the same way.
  {
    std::ofstream(replay.backend.sim_world)
        << worldYaml(second.truth, testing::writeExactRobot(elsewhere.path + "/exact-robot.yaml"));
  }
  const Session again = runOnce(replay);
  ASSERT_TRUE(again.result.truth && again.result.truth->noise_seed);
  EXPECT_EQ(*again.result.truth->noise_seed, *second.result.truth->noise_seed);
  // The same to the rounding of the file's 17 digits (the PSD's rotation goes through
  // roll-pitch-yaw, which moves where the servo aims by a few nanometres): far below the noise,
  // where another stream differs by about a sigma.
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& p = second.result.report.parameters[k];
    EXPECT_NEAR(again.result.report.parameters[k].value, p.value, 0.01 * p.sigma) << unknownName(k);
  }
}

TEST(RobotLife, AMotorReplacementMovesThatZeroInTheTruthAndInTheResult) {
  const testing::TempDir dir("zerocal-life");
  const Session before = runOnce(idealWorld(dir.path + "/before"));
  DaemonConfig changed = idealWorld(dir.path + "/after");
  changed.backend.sim_zero_change_joint = 3;
  changed.backend.sim_zero_change_deg = 0.1;
  const Session after = runOnce(changed);
  ASSERT_TRUE(before.result.truth && after.result.truth);
  // delta3 is the second offset (delta2 .. delta5).
  for (int k = 0; k < kOffsetCount; ++k)
    EXPECT_NEAR(after.result.truth->offsets_deg[k] - before.result.truth->offsets_deg[k],
                k == 1 ? 0.1 : 0.0, 1e-12)
        << unknownName(k);
  EXPECT_NEAR(after.truth.true_offsets_deg[2] - before.truth.true_offsets_deg[2], 0.1, 1e-12);
  // The calibration sees it: +0.1 deg on delta3 within a few sigma, the others unmoved.
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& a = before.result.report.parameters[k];
    const ParameterEstimate& b = after.result.report.parameters[k];
    const double expected = k == 1 ? 0.1 : 0.0;
    EXPECT_LT(std::abs(b.value - a.value - expected), 4 * std::hypot(a.sigma, b.sigma))
        << unknownName(k) << ": " << b.value - a.value;
  }
}

// backend.sim_warm_s: the daemon starts its simulated controller with that much time behind it,
// the arm as warm as that; without it, cold (the controller's clock at 0), as before.
TEST(RobotLife, TheDaemonStartsTheSimulatedArmAsWarmAsConfigured) {
  const testing::TempDir dir("zerocal-life");
  DaemonConfig c = idealWorld(dir.path);
  c.backend.sim_ideal_world = false;  // the realistic world warms
  for (const double warm_s : {0.0, 3600.0}) {
    c.backend.sim_warm_s = warm_s;
    const std::unique_ptr<CellBackend> backend = service::makeBackend(c);
    auto* sim = dynamic_cast<sim::SimBackend*>(backend.get());
    ASSERT_NE(sim, nullptr);
    EXPECT_EQ(sim->cell().controller().simTimeS(), warm_s);
    // The cell's clock goes on from there; a session's cell time is a difference of it.
    EXPECT_GE(sim->cell().nowS(), warm_s);
    EXPECT_LT(sim->cell().nowS(), warm_s + 1);
  }
}

TEST(RobotLife, AZeroChangeTheConfigurationLetThroughIsRefusedByTheBackend) {
  const testing::TempDir dir("zerocal-life");
  DaemonConfig c = idealWorld(dir.path);
  c.backend.sim_zero_change_joint = 6;
  c.backend.sim_zero_change_deg = 0.1;
  try {
    service::makeBackend(c);
    ADD_FAILURE() << "joint 6's zero was changed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("joints 2..5"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace zerocal
