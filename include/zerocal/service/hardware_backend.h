// The real cell: the controller and the PSD readout that controller.kind and daq.kind name (the
// cell factory makes them: today the IRC5 over TCP and the USB-1408FS through libusb), configured
// from the daemon's configuration. Nothing is opened until a session connects.
#pragma once

#include "zerocal/cell/cell.h"
#include "zerocal/daemon/config.h"
#include "zerocal/psd/psd.h"

namespace zerocal::service {

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
