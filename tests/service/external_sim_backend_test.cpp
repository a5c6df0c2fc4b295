// The sim backend with an external zerocal-sim: a SimController on loopback port 0 stands in for
// the other process; the daemon's backend, built from the configuration as zerocald builds it,
// drives it through the production Irc5Client and reads the in-process simulated board lit where
// the external simulator says the beam is.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <variant>

#include "stored_plan_request.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal::service {
namespace {

struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-extsim-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

// The ideal world (results are checked against the truth), on both sides.
SimControllerOptions externalSim(std::uint64_t seed) {
  SimControllerOptions o;
  o.world = randomWorld(seed, WorldKind::kIdeal);
  o.seed = seed;
  return o;
}

DaemonConfig configFor(const SimController& sim, std::uint64_t seed, const std::string& dir) {
  DaemonConfig c;
  c.backend.kind = BackendKind::kSim;
  c.backend.sim_seed = seed;
  c.backend.sim_ideal_world = true;
  c.backend.sim_host = "127.0.0.1";
  c.backend.sim_port = sim.port();
  c.servo.settle_s = 0.0;  // the cell clock is the steady clock: waits are real
  c.session.data_dir = dir + "/sessions";
  return c;
}

TEST(ExternalSim, ProtocolExtensionsAnswerTheSpotAndTheWorld) {
  SimController sim(externalSim(4));
  sim.start();
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = sim.port();
  o.robot = sim.world().robot;
  Irc5Client client(o);
  client.connect();
  const SimWorldId id = client.readSimWorldId();
  EXPECT_EQ(id.hash, worldHash(randomWorld(4, WorldKind::kIdeal)));
  EXPECT_NE(id.hash, worldHash(randomWorld(5, WorldKind::kIdeal)));
  EXPECT_EQ(id.seed, 4u);
  const auto spot = client.readSimBeamSpot();
  const std::optional<BeamHit> hit = sim.beamHitNow();
  ASSERT_EQ(spot.has_value(), hit.has_value());
  if (hit) {
    EXPECT_NEAR(spot->u_mm, hit->spot.u_mm, 1e-5);
    EXPECT_NEAR(spot->v_mm, hit->spot.v_mm, 1e-5);
  }
}

TEST(ExternalSim, SessionRunsToTheWorldsTruth) {
  constexpr std::uint64_t kSeed = 7;
  TempDir dir;
  SimController sim(externalSim(kSeed));
  sim.start();
  const DaemonConfig config = configFor(sim, kSeed, dir.path);
  const std::unique_ptr<CellBackend> backend = makeBackend(config);
  EXPECT_STREQ(backend->name(), "sim");

  SessionManager manager(*backend, managerSettingsOf(config));
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-7"));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  // The servo's link and the board's spot link, both to the external simulator.
  EXPECT_GE(sim.connectionCount(), 2);
  const nlohmann::json result = toJson(manager.result(id));
  const World truth = randomWorld(kSeed, WorldKind::kIdeal);
  for (int k = 0; k < kOffsetCount; ++k) {
    const std::string name = unknownName(k);
    const double error =
        result["parameters"][name]["value"].get<double>() - truth.true_offsets_deg[k + 1];
    EXPECT_LT(std::abs(error), 3 * result["parameters"][name]["sigma"].get<double>()) << name;
    EXPECT_NEAR(result["truth"][name].get<double>(), truth.true_offsets_deg[k + 1], 1e-12);
  }
}

// The daemon keeps its links to the cell between sessions. A controller restarted in between
// (another client's apply, a power cycle) has dropped them all; the next session notices at its
// first request and makes both links again instead of reading a dead spot link as "no light".
TEST(ExternalSim, ASessionAfterAControllerRestartMakesItsLinksAgain) {
  constexpr std::uint64_t kSeed = 7;
  TempDir dir;
  SimController sim(externalSim(kSeed));
  sim.start();
  const DaemonConfig config = configFor(sim, kSeed, dir.path);
  const std::unique_ptr<CellBackend> backend = makeBackend(config);
  SessionManager manager(*backend, managerSettingsOf(config));
  manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-7"));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);

  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = sim.port();
  o.robot = sim.world().robot;
  Irc5Client other(o);
  other.connect();
  other.restartController();
  ASSERT_EQ(sim.restartCount(), 1);

  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-7"));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  const nlohmann::json result = toJson(manager.result(id));
  EXPECT_EQ(result["cell"]["controller"]["serial"], "SIM-1600-0001");
  EXPECT_TRUE(result.contains("controller_cal_offset_rad"));
}

// The board is lit where zerocal-sim says the beam is, asked over a link of its own. When that
// link drops after pose 2 (`times` requests for the beam close it), a reading is no reading: not
// a dark detector, a spot "not found" with a good pose offered to skip.
struct SpotLinkDropped {
  SessionStatus end;
  nlohmann::json result;  // when done
};
SpotLinkDropped dropTheSpotLinkAfterPose2(int times, const std::string& dir) {
  constexpr std::uint64_t kSeed = 7;
  SimController sim(externalSim(kSeed));
  sim.start();
  const DaemonConfig config = configFor(sim, kSeed, dir);
  const std::unique_ptr<CellBackend> backend = makeBackend(config);
  SessionManager manager(*backend, managerSettingsOf(config));
  std::atomic<bool> dropped{false};
  manager.setEventSink([&](const SessionEvent& e) {
    const auto* pose = std::get_if<PoseEvent>(&e);
    if (!pose || pose->record.planIndex() != 1 || dropped.exchange(true)) return;
    SimFaults f;
    f.drop_code = irc5::kSimBeamSpot;
    f.drop_code_times = times;
    sim.setFaults(f);
  });
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-7"));
  SpotLinkDropped out{manager.waitIdle(), {}};
  manager.setEventSink(nullptr);
  EXPECT_TRUE(dropped.load());
  if (out.end.state == SessionState::kDone) out.result = toJson(manager.result(id));
  return out;
}

TEST(ExternalSim, ALostSpotLinkIsMadeAgainAndThePoseMeasuredNoneSkipped) {
  TempDir dir;
  const SpotLinkDropped run = dropTheSpotLinkAfterPose2(1, dir.path);
  ASSERT_EQ(run.end.state, SessionState::kDone) << run.end.message;
  EXPECT_EQ(run.end.skippable_pose, 0);
  EXPECT_EQ(run.result["poses"], 8);  // every pose measured, pose 3 among them
  for (const auto& pose : run.result["pose_breakdown"]) EXPECT_FALSE(pose.contains("skipped"));
  EXPECT_EQ(run.result["recoveries"]["reopens"], 1);
}

TEST(ExternalSim, ASpotLinkThatStaysDownIsNamedAndNoPoseIsOfferedToSkip) {
  TempDir dir;
  const SpotLinkDropped run = dropTheSpotLinkAfterPose2(1000, dir.path);
  ASSERT_EQ(run.end.state, SessionState::kFaulted) << run.end.message;
  EXPECT_NE(run.end.message.find("pose 3 of 8"), std::string::npos) << run.end.message;
  EXPECT_NE(run.end.message.find("the link to the simulated controller that says where the beam "
                                 "meets the PSD failed"),
            std::string::npos)
      << run.end.message;
  EXPECT_EQ(run.end.message.find("spot not found"), std::string::npos) << run.end.message;
  EXPECT_EQ(run.end.message.find("--skip-pose"), std::string::npos) << run.end.message;
  EXPECT_EQ(run.end.skippable_pose, 0);
}

TEST(ExternalSim, AMismatchedWorldIsRefusedBeforeAnythingMoves) {
  TempDir dir;
  SimController sim(externalSim(5));
  sim.start();
  const DaemonConfig config = configFor(sim, 6, dir.path);
  const std::unique_ptr<CellBackend> backend = makeBackend(config);
  try {
    backend->connect();
    FAIL() << "a zerocal-sim of another world was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(worldHash(randomWorld(5, WorldKind::kIdeal))), std::string::npos) << what;
    EXPECT_NE(what.find(worldHash(randomWorld(6, WorldKind::kIdeal))), std::string::npos) << what;
    EXPECT_NE(what.find("--seed 5"), std::string::npos) << what;
    EXPECT_NE(what.find("backend.sim_seed 6"), std::string::npos) << what;
  }

  const Joints before = sim.commandedJoints();
  SessionManager manager(*backend, managerSettingsOf(config));
  manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-6"));  // this daemon's world
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kFaulted);
  EXPECT_NE(end.message.find("simulates world"), std::string::npos) << end.message;
  EXPECT_EQ(sim.commandedJoints(), before);
}

// zerocal-sim's world is fixed: a session at several PSD placements is refused before anything
// is planned or created, with the reason; one placement runs as ever.
TEST(ExternalSim, SeveralPlacementsAreRefusedWithTheReason) {
  TempDir dir;
  SimController sim(externalSim(7));
  sim.start();
  const DaemonConfig config = configFor(sim, 7, dir.path);
  const std::unique_ptr<CellBackend> backend = makeBackend(config);
  EXPECT_NE(backend->placementsRefusal().find("in-process"), std::string::npos);
  SessionManager manager(*backend, managerSettingsOf(config));
  StartRequest request = manager.defaultRequest();
  request.placements = 2;
  try {
    manager.start(request);
    FAIL() << "a session at two placements was started on an external zerocal-sim";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "unsupported");
    EXPECT_NE(std::string(e.what()).find("cannot move its PSD"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(manager.sessions().empty());
}

// By default both sides draw the seed's realistic world with the same gross-error rate: they
// agree; and a daemon on the ideal world is refused by a zerocal-sim on the realistic one.
TEST(ExternalSim, TheDefaultRealisticWorldsOfDaemonAndZerocalSimAgree) {
  TempDir dir;
  SimControllerOptions o;
  o.world = randomWorld(9);  // what zerocal-sim --seed 9 simulates
  o.seed = 9;
  SimController sim(o);
  sim.start();
  DaemonConfig config = configFor(sim, 9, dir.path);
  config.backend.sim_ideal_world = false;
  EXPECT_NO_THROW(makeBackend(config)->connect());
  config.backend.sim_ideal_world = true;
  EXPECT_THROW(makeBackend(config)->connect(), ConfigError);
}

}  // namespace
}  // namespace zerocal::service
