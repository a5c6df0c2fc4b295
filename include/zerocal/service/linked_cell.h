// The connected cell of both backends: an Irc5Client, a Usb1408fs and the PSD chain reading it,
// on a given clock. The hardware backend opens libusb and the steady clock; the simulated one the
// simulated board and the simulated cell's clock; the code in between is the same.
#pragma once

#include "zerocal/cell/cell.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/psd/psd.h"
#include "zerocal/servo/psd_reader.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::service {

class LinkedCell : public ConnectedCell {
 public:
  // Opens the board, then connects the controller. Throws as Usb1408fs and Irc5Client::connect.
  LinkedCell(Irc5Options controller, usb1408fs::Usb1408fs::Opener board, const psd::PsdMap& map,
             CellClock& clock, servo::ChainPsdReaderOptions reader = {});
  ~LinkedCell() override;

  ControllerLink& robot() override { return client_; }
  PsdReader& psd() override { return psd_; }
  CellClock& clock() override { return clock_; }
  void reconnectRobot() override;
  void reopenPsd() override;
  void stopRobot() noexcept override;

 private:
  CellClock& clock_;
  Irc5Client client_;
  usb1408fs::Usb1408fs daq_;
  servo::ChainPsdReader psd_;
};

}  // namespace zerocal::service
