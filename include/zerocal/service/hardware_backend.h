// The real cell: the IRC5 over TCP (Irc5Client, the RAPID server in drivers/irc5/rapid) and the
// USB-1408FS through libusb reading the PSD's conditioning board, configured from the daemon's
// configuration. Nothing is opened until a session connects.
#pragma once

#include "zerocal/cell/cell.h"
#include "zerocal/daemon/config.h"
#include "zerocal/irc5/irc5_client.h"

namespace zerocal::service {

// The client options the controller section describes (robot file, address, timeouts, speeds,
// margins). Used for the simulated controller too, so that both obey the same configuration.
Irc5Options irc5OptionsOf(const ControllerConfig& config, Irc5Options base = {});

// The PSD's orientation in the base frame from roll, pitch, yaw in degrees (fixed axes x, y, z):
// columns u, v and normal. [0, 0, 0] is a detector facing straight up.
Eigen::Matrix3d psdRotationOf(const std::array<double, 3>& rpy_deg);

class HardwareBackend final : public CellBackend {
 public:
  // Loads the robot file and the PSD map. Throws ConfigError naming the key.
  explicit HardwareBackend(const DaemonConfig& config);
  const char* name() const override { return "hardware"; }
  CellKnowledge knowledge() const override { return knowledge_; }
  std::unique_ptr<ConnectedCell> connect() override;

 private:
  DaemonConfig config_;
  CellKnowledge knowledge_;
  psd::PsdMap map_;
};

}  // namespace zerocal::service
