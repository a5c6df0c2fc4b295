#include "zerocal/service/linked_cell.h"

namespace zerocal::service {

LinkedCell::LinkedCell(std::unique_ptr<ControllerConnection> robot, std::unique_ptr<PsdReadout> psd,
                       CellClock& clock)
    : clock_(clock), robot_(std::move(robot)), psd_(std::move(psd)) {
  robot_->connect();
}

LinkedCell::~LinkedCell() { robot_->close(); }

void LinkedCell::reconnectRobot() { robot_->reconnect(); }

void LinkedCell::reopenPsd() { psd_->reopen(); }

void LinkedCell::stopRobot() noexcept {
  try {
    if (robot_->connected()) robot_->stop();
  } catch (const std::exception&) {
    // Unreachable controller: the controller's server stops serving moves when its client goes
    // away, and a move in progress ends at its target.
  }
}

}  // namespace zerocal::service
