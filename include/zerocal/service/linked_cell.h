// The connected cell of every backend: a controller connection and a PSD readout, whatever their
// vendors, on a given clock. The hardware backend makes its devices through the cell factory
// (cell_factory.h) from controller.kind and daq.kind; the simulated backends make the IRC5 client
// and the USB-1408FS readout over their simulated peers. The code in between is the same.
#pragma once

#include <memory>

#include "zerocal/cell/cell.h"

namespace zerocal::service {

class LinkedCell : public ConnectedCell {
 public:
  // Takes the devices (the readout's board is open already) and connects the controller. Throws
  // as ControllerConnection::connect.
  LinkedCell(std::unique_ptr<ControllerConnection> robot, std::unique_ptr<PsdReadout> psd,
             CellClock& clock);
  ~LinkedCell() override;

  ControllerLink& robot() override { return *robot_; }
  PsdReader& psd() override { return *psd_; }
  CellClock& clock() override { return clock_; }
  ControllerCalibration* calibration() override { return robot_->calibration(); }
  void reconnectRobot() override;
  void reopenPsd() override;
  void stopRobot() noexcept override;

 private:
  CellClock& clock_;
  std::unique_ptr<ControllerConnection> robot_;
  std::unique_ptr<PsdReadout> psd_;
};

}  // namespace zerocal::service
