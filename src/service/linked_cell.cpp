#include "zerocal/service/linked_cell.h"

namespace zerocal::service {

LinkedCell::LinkedCell(Irc5Options controller, usb1408fs::Usb1408fs::Opener board,
                       const psd::PsdMap& map, CellClock& clock,
                       servo::ChainPsdReaderOptions reader)
    : clock_(clock),
      client_(std::move(controller)),
      daq_(std::move(board)),
      psd_(daq_, map, clock, std::move(reader)) {
  client_.connect();
}

LinkedCell::~LinkedCell() { client_.close(); }

void LinkedCell::reconnectRobot() { client_.reconnect(); }

void LinkedCell::reopenPsd() { daq_.reopen(); }

void LinkedCell::stopRobot() noexcept {
  try {
    if (client_.connected()) client_.stop();
  } catch (const std::exception&) {
    // Unreachable controller: the RAPID server stops serving moves when its client goes away,
    // and a move in progress ends at its target.
  }
}

}  // namespace zerocal::service
