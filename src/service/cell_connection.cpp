#include "zerocal/service/cell_connection.h"

#include <algorithm>
#include <thread>

#include "zerocal/cell/link_error.h"
#include "zerocal/daemon/logging.h"

namespace zerocal::service {

CellConnection::CellConnection(CellBackend& backend, SessionWorker& worker)
    : backend_(backend), worker_(worker), backend_name_(backend.name()) {}

CellConnection::~CellConnection() {
  stopRobot();
  cell_.reset();
}

ConnectedCell& CellConnection::connect() {
  if (!cell_) cell_ = backend_.connect();
  return *cell_;
}

void CellConnection::stopRobot() noexcept {
  if (cell_) cell_->stopRobot();
}

void CellConnection::connectWaitingForRestart(std::chrono::milliseconds timeout,
                                              const std::atomic<bool>& abort) {
  if (cell_) return;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::chrono::milliseconds pause(100);
  bool said = false;
  for (;;) {
    worker_.markProgress();
    try {
      cell_ = backend_.connect();
      return;
    } catch (const LinkError& e) {
      if (e.kind() != LinkError::Kind::kTransient || abort.load() ||
          std::chrono::steady_clock::now() + pause >= deadline)
        throw;
      if (!said)
        makeLogger("apply")->warn(
            "the controller does not serve ({}); it may be restarting: waiting up to {} s",
            e.what(), timeout.count() / 1000);
      said = true;
    }
    std::this_thread::sleep_for(pause);
    pause = std::min(2 * pause, std::chrono::milliseconds(2000));
  }
}

CellIdentity CellConnection::identify(const std::string& id) {
  auto log = makeLogger("session");
  CellIdentity identity;
  // The links are kept between sessions; a controller restarted meanwhile (an apply by another
  // client, a power cycle) has dropped them, and this first request is where that shows: both
  // links are made again before anything moves, or the PSD's would read as no light.
  try {
    try {
      identity.robot = cell_->robot().robotInfo();
    } catch (const LinkError& e) {
      if (e.kind() != LinkError::Kind::kTransient) throw;
      log->info(
          "session {}: the link to the controller was lost since the last session ({}): "
          "connecting again",
          id, e.what());
      cell_->reconnectRobot();
      identity.robot = cell_->robot().robotInfo();
    }
    log->info("session {}: {} serial {}, controller software {}", id, identity.robot.robot_type,
              identity.robot.serial, identity.robot.software_version);
  } catch (const std::exception& e) {
    log->warn("session {}: the controller did not identify the robot: {}", id, e.what());
  }
  if (ControllerCalibration* calibration = cell_->calibration()) {
    try {
      identity.cal_offset_rad = calibration->readCalOffsets();
    } catch (const std::exception& e) {
      log->warn("session {}: the controller did not report its cal_offset values: {}", id,
                e.what());
    }
  }
  return identity;
}

}  // namespace zerocal::service
