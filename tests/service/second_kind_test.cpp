// A second controller kind is a folder of its own and a registration: the "line" controller
// (line_kind.h: another wire protocol, its own configuration section and motion model) drives the
// simulated arm through a whole calibration, set up from the daemon's configuration by the same
// setup as zerocald (managerSettingsOf, makeControllerConnection), with no IRC5 anywhere.
#include <gtest/gtest.h>

#include <cmath>

#include "exact_robot.h"
#include "line_kind.h"
#include "stored_plan_request.h"
#include "temp_dir.h"
#include "zerocal/calib/cell_model.h"
#include "zerocal/cell/kinds.h"
#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/service/cell_factory.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/service/linked_cell.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/simulated_cell.h"
#include "zerocal/sim/simulated_rig.h"
#include "zerocal/store/session_files.h"
#include "zerocal/usb1408fs/psd_readout.h"

namespace zerocal::service {
namespace {

using zerocal::testing::LineServer;
using zerocal::testing::LineSettings;

sim::SimulatedArmOptions armOptions(const World& world) {
  sim::SimulatedArmOptions o;
  o.world = world;
  o.motion = zerocal::testing::LineMotion{}.model();
  o.seed = 13;
  o.identity = {"LINE-0001", "line-1.0", "line-arm"};
  return o;
}

// The cell of a line controller: the simulated arm behind the line server, the simulated
// USB-1408FS lit where the arm's beam meets the PSD, and the session's clock (the arm's time and
// the board's). The link is the one the configuration's controller kind makes.
class LineCellBackend final : public CellBackend, public CellClock {
 public:
  explicit LineCellBackend(const World& world)
      : world_(world),
        arm_(armOptions(world)),
        server_(arm_),
        map_(sim::simulatedPsdMap(psd_options_, 0.8, 0.04)) {
    board_.setAnalogSource(sim::psdAnalogSource(psd_, [this](double) -> std::optional<PsdSpot> {
      const std::optional<BeamHit> hit = arm_.beamHitNow();
      if (!hit) return std::nullopt;
      return hit->spot;
    }));
  }
  const char* name() const override { return "line"; }
  CellKnowledge knowledge() const override {
    const sim::SessionKnowledge k = sim::knowledgeOf(world_);
    return {k.cell, k.taught_centre, "simulated bench sweep, fingerprint " + map_.fingerprint()};
  }
  std::string placementsRefusal() const override { return "one placement"; }
  std::unique_ptr<ConnectedCell> connect() override {
    const sim::SimulatedReadout readout = sim::simulatedReadout();
    return std::make_unique<LinkedCell>(
        makeControllerConnection(controller_),
        std::make_unique<usb1408fs::Usb1408fsReadout>(sim::FakeTransport::opener(board_), map_,
                                                      *this, readout.board, readout.psd),
        *this);
  }
  double nowS() noexcept override {
    return arm_.timeS() + std::chrono::duration<double>(board_.now()).count() + waited_s_;
  }
  void waitS(double seconds) noexcept override {
    if (seconds > 0) waited_s_ += seconds;
  }

  // The controller section the links are made from (its kind, its address).
  void configure(const ControllerConfig& controller) { controller_ = controller; }
  sim::SimulatedArm& arm() { return arm_; }
  LineServer& server() { return server_; }

 private:
  World world_;
  ControllerConfig controller_;
  sim::SimulatedArm arm_;
  LineServer server_;
  sim::PsdModelOptions psd_options_{};
  sim::PsdModel psd_{psd_options_};
  sim::Usb1408fsModel board_{1408};
  psd::PsdMap map_;
  double waited_s_ = 0;
};

class SecondControllerKind : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { kinds::registerControllerKind(zerocal::testing::lineKind()); }
};

TEST_F(SecondControllerKind, CalibratesTheSimulatedArmThroughItsOwnProtocol) {
  const World world = randomWorld(13, WorldKind::kIdeal);
  zerocal::testing::TempDir dir;

  // The technician's configuration: the line controller at its address, the PSD as taught.
  DaemonConfig config;
  ConfigOrigins origins;
  std::vector<std::string> problems;
  applyConfigOverride(config, "controller.kind=line", origins, problems);
  applyConfigOverride(config, "controller.line.limit_margin_deg=2", origins, problems);
  config.session.data_dir = dir.path + "/sessions";
  const Eigen::Vector3d taught = sim::knowledgeOf(world).taught_centre;
  config.session.target_mm = {taught.x(), taught.y(), taught.z()};
  // The ideal world's links are the robot file's exactly, and it has no sag.
  config.controller.robot = testing::writeExactRobot(dir.path + "/exact-robot.yaml");

  LineCellBackend cell(world);
  config.controller.sections.get<LineSettings>("line")->port = cell.server().port();
  for (const auto& p : validateDaemonConfig(config, origins)) problems.push_back(p);
  ASSERT_TRUE(problems.empty()) << problems.front();
  cell.configure(config.controller);

  // The kind's motion model, not the IRC5's, orders the plan and bounds the servo's moves.
  const ManagerSettings settings = managerSettingsOf(config);
  const Joints from{0, 0, 0, 0, 30, 0}, to{20, 25, -10, 40, 60, -30};
  EXPECT_DOUBLE_EQ(settings.travel_s(builtinIrb1600(), from, to), 40.0 / 60.0);
  EXPECT_EQ(settings.run.servo.limit_margin_deg, 2.0);

  SessionManager manager(cell, settings);
  const std::string id =
      manager.start(zerocal::testing::onStoredPlan(manager.defaultRequest(), "ideal-13"));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;

  const nlohmann::json result = toJson(manager.result(id));
  for (int k = 0; k < kOffsetCount; ++k) {
    const std::string name = unknownName(k);
    const double error =
        result["parameters"][name]["value"].get<double>() - world.true_offsets_deg[k + 1];
    EXPECT_LT(std::abs(error), 4 * result["parameters"][name]["sigma"].get<double>()) << name;
  }
  // Every move went over the line protocol to the arm, none over another link.
  EXPECT_GT(cell.arm().motionTotals().moves, 16);
  EXPECT_GT(cell.server().requests(), cell.arm().motionTotals().moves);
}

// The simulated cell's controller speaks the IRC5 protocol only: a daemon configured with
// another kind and backend.kind: sim is refused when it sets up, naming the key.
TEST_F(SecondControllerKind, TheSimulatedCellRefusesAKindItCannotServe) {
  DaemonConfig config;
  config.backend.kind = BackendKind::kSim;
  config.backend.sim_ideal_world = true;
  config.controller.kind = "line";
  try {
    makeBackend(config);
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("controller.kind"), std::string::npos) << e.what();
  }
  config.controller.kind = "irc5";
  EXPECT_NO_THROW(makeBackend(config));
}

}  // namespace
}  // namespace zerocal::service
