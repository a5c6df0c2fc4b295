// The hardware backend, as configured for a real cell, on the simulated cell: the controller
// section points the Irc5Client at the simulated IRC5's TCP port, and the USB-1408FS is the
// simulated board behind umockdev, opened by serial number through the real LibusbTransport and
// libusb's Linux code. Its analog inputs come from the simulated PSD at the simulated robot's beam.
// So the code a cell PC runs, from the configuration to the result, runs here unchanged.
// Runs under umockdev-wrapper (tests/service/CMakeLists.txt).
#include "zerocal/service/hardware_backend.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "exact_robot.h"
#include "stored_plan_request.h"
#include "umockdev_board.h"
#include "zerocal/irc5/irc5_kind.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/simulated_cell.h"
#include "zerocal/sim/simulated_rig.h"
#include "zerocal/usb1408fs/usb1408fs_kind.h"

namespace zerocal::service {
namespace {

struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-hw-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

// The fixed-axes roll, pitch, yaw (deg) of a rotation, as session.psd_rpy_deg takes them.
std::array<double, 3> rpyDegOf(const Eigen::Matrix3d& r) {
  const Eigen::Vector3d ypr = r.eulerAngles(2, 1, 0) / kDegToRad;
  return {ypr[2], ypr[1], ypr[0]};
}

class HardwareBackendOnSimulatedCell : public ::testing::Test {
 protected:
  HardwareBackendOnSimulatedCell() : cell_(cellOptions()), psd_(cellOptions().psd) {
    SimController* controller = &cell_.controller();
    board_.withModel([&](sim::Usb1408fsModel& m) {
      m.setAnalogSource(sim::psdAnalogSource(psd_, [controller](double) {
        std::optional<PsdSpot> spot;
        if (const std::optional<BeamHit> hit = controller->beamHitNow()) spot = hit->spot;
        return spot;
      }));
      return 0;
    });
    // What the technician configures: the controller's address, the board's serial, the map from
    // the PSD rig, the taught PSD centre and its orientation.
    const World& world = cell_.world();
    config_.backend.kind = BackendKind::kHardware;
    Irc5Options& link = config_.controller.sections.get<irc5::Irc5Settings>("irc5")->options;
    link.host = "127.0.0.1";
    link.port = cell_.controller().port();
    usb1408fs::BoardSettings& board = boardOf(config_);
    board.serial = "01A2B3C4";
    board.samples_per_reading = 32;
    board.scan_rate_hz = 16000;
    config_.daq.psd.map_file = dir_.path + "/psd-map.yaml";
    std::ofstream(config_.daq.psd.map_file) << psd::psdMapToYaml(cell_.psdMap());
    const Eigen::Vector3d taught = sim::knowledgeOf(world).taught_centre;
    config_.session.target_mm = {taught.x(), taught.y(), taught.z()};
    config_.session.psd_rpy_deg = rpyDegOf(world.psd_rotation);
    config_.session.data_dir = dir_.path + "/sessions";
    // The cell behind the board and the port is the ideal world: its links are the robot
    // file's exactly, it has no sag, and the result is checked against its truth.
    config_.controller.robot = testing::writeExactRobot(dir_.path + "/exact-robot.yaml");
  }

  static usb1408fs::BoardSettings& boardOf(DaemonConfig& config) {
    return config.daq.boards.get<usb1408fs::Usb1408fsSettings>("usb-1408fs")->board;
  }

  static sim::SimulatedCellOptions cellOptions() {
    sim::SimulatedCellOptions o;
    o.world = randomWorld(13, WorldKind::kIdeal);  // the result is checked against the truth
    o.controller_seed = 13;
    o.psd.seed = 113;
    return o;
  }

  sim::UmockdevBoard board_;  // before anything initialises libusb
  TempDir dir_;
  sim::SimulatedCell cell_;
  sim::PsdModel psd_;
  DaemonConfig config_;
};

TEST_F(HardwareBackendOnSimulatedCell, KnowsTheCellFromItsConfiguration) {
  const HardwareBackend backend(config_);
  const CellKnowledge k = backend.knowledge();
  EXPECT_TRUE(k.cell.psd_rotation.isApprox(cell_.world().psd_rotation, 1e-9));
  EXPECT_NEAR(k.taught_centre_mm.x(), config_.session.target_mm[0], 1e-12);
  EXPECT_EQ(k.cell.robot.name, cell_.world().robot.name);

  DaemonConfig no_map = config_;
  no_map.daq.psd.map_file.clear();
  EXPECT_THROW(HardwareBackend{no_map}, ConfigError);
}

TEST_F(HardwareBackendOnSimulatedCell, ConnectsReadsAndCalibratesThroughLibusbAndTcp) {
  HardwareBackend backend(config_);
  {
    const std::unique_ptr<ConnectedCell> cell = backend.connect();
    const Joints q = cell->robot().readJoints();
    EXPECT_NEAR(q[4], 30.0, 1e-3);  // the simulated controller's start pose
    const PsdReading r = cell->psd().read();
    EXPECT_TRUE(std::isfinite(r.sum_v));
  }
  DaemonConfig wrong_serial = config_;
  boardOf(wrong_serial).serial = "NOSUCHBOARD";
  HardwareBackend absent(wrong_serial);
  EXPECT_THROW(absent.connect(), Error);

  // Settled as zerocald settles it from the configuration; on the optimal plan for this world,
  // stored.
  SessionManager manager(backend, managerSettingsOf(config_));
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-13"));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  const nlohmann::json result = toJson(manager.result(id));
  EXPECT_FALSE(result.contains("truth"));  // a real cell does not know it
  for (int k = 0; k < kOffsetCount; ++k) {
    const std::string name = unknownName(k);
    const double error =
        result["parameters"][name]["value"].get<double>() - cell_.world().true_offsets_deg[k + 1];
    EXPECT_LT(std::abs(error), 4 * result["parameters"][name]["sigma"].get<double>()) << name;
  }
}

}  // namespace
}  // namespace zerocal::service
