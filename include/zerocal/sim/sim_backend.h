// The simulated cell as the daemon's backend: one SimulatedCell that lives as long as the daemon
// (the robot stays where it was left between sessions, as a real one does), and per session the
// production endpoints attached to it: the real Irc5Client over loopback TCP, the real Usb1408fs
// protocol code over the byte-exact simulated board, and the real PSD chain.
#pragma once

#include <functional>
#include <memory>

#include "zerocal/service/cell.h"
#include "zerocal/sim/simulated_cell.h"

namespace zerocal::sim {

class SimBackend final : public service::CellBackend {
 public:
  // `adjust` may change the client's options (speeds, margins) before it connects, as the
  // controller section of the configuration does for a real controller.
  explicit SimBackend(SimulatedCellOptions options, std::function<void(Irc5Options&)> adjust = {});
  const char* name() const override { return "sim"; }
  service::CellKnowledge knowledge() const override;
  std::unique_ptr<service::ConnectedCell> connect() override;

  SimulatedCell& cell() { return cell_; }

 private:
  SimulatedCell cell_;
  std::function<void(Irc5Options&)> adjust_;
};

}  // namespace zerocal::sim
