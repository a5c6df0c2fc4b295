#include "zerocal/service/hardware_backend.h"

#include <Eigen/Geometry>

#include "zerocal/model/kinematics.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/service/cell_factory.h"
#include "zerocal/service/linked_cell.h"

namespace zerocal::service {
namespace {

// Base-from-member: the steady clock is constructed before the LinkedCell that refers to it.
struct SteadyClockHolder {
  SteadyCellClock steady_clock;
};

class HardwareCell final : private SteadyClockHolder, public LinkedCell {
 public:
  HardwareCell(const DaemonConfig& config, const psd::PsdMap& map)
      : LinkedCell(makeControllerConnection(config.controller),
                   makePsdReadout(config.daq, map, steady_clock), steady_clock) {}
};

}  // namespace

Eigen::Matrix3d psdRotationOf(const std::array<double, 3>& rpy) {
  return (Eigen::AngleAxisd(rpy[2] * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy[1] * kDegToRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy[0] * kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

HardwareBackend::HardwareBackend(const DaemonConfig& config)
    : config_(config),
      map_(config.daq.psd.map_file.empty()
               ? throw ConfigError("daq.map_file",
                                   {"the hardware backend needs the PSD map (from `zerocal "
                                    "psd-map`): set daq.map_file"})
               : psd::loadPsdMap(config.daq.psd.map_file)) {
  knowledge_.cell.robot = robotOf(config.controller);
  knowledge_.cell.psd_rotation = psdRotationOf(config.session.psd_rpy_deg);
  const auto& t = config.session.target_mm;
  knowledge_.taught_centre_mm = Eigen::Vector3d(t[0], t[1], t[2]);
  knowledge_.psd_map = config.daq.psd.map_file + ", fingerprint " + map_.fingerprint();
}

std::unique_ptr<ConnectedCell> HardwareBackend::connect() {
  return std::make_unique<HardwareCell>(config_, map_);
}

}  // namespace zerocal::service
