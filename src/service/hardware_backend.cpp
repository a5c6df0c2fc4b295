#include "zerocal/service/hardware_backend.h"

#include <Eigen/Geometry>

#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/service/linked_cell.h"
#include "zerocal/usb1408fs/libusb_transport.h"

namespace zerocal::service {
namespace {

servo::ChainPsdReaderOptions readerOptionsOf(const DaqConfig& daq) {
  servo::ChainPsdReaderOptions o;
  o.channels = daq.channels;
  o.samples = static_cast<std::size_t>(daq.samples_per_reading);
  o.rate_hz = daq.scan_rate_hz;
  o.on_threshold_v = daq.sum_threshold_v;
  o.off_threshold_v = 0.8 * daq.sum_threshold_v;  // hysteresis: no flicker at the edge
  return o;
}

// Base-from-member: the steady clock is constructed before the LinkedCell that refers to it.
struct SteadyClockHolder {
  SteadyCellClock steady_clock;
};

class HardwareCell final : private SteadyClockHolder, public LinkedCell {
 public:
  HardwareCell(Irc5Options options, const DaqConfig& daq, const psd::PsdMap& map)
      : LinkedCell(
            std::move(options),
            [serial = daq.serial] { return usb1408fs::LibusbTransport::open(serial); }, map,
            steady_clock, readerOptionsOf(daq)) {}
};

}  // namespace

Irc5Options irc5OptionsOf(const ControllerConfig& c, Irc5Options o) {
  o.robot = c.robot == "builtin" ? builtinIrb1600() : loadRobot(c.robot);
  o.limit_margin_deg = c.limit_margin_deg;
  // No step limit on the client: the moves between planned poses span up to ~240 deg of wrist
  // rotation by design (checked against the limits and previewed before the session). The small
  // servo moves are bounded by the servo itself (servo.max_step_deg <= controller.max_step_deg).
  o.connect_timeout = c.connect_timeout;
  o.request_timeout = c.request_timeout;
  o.move_timeout_factor = c.move_timeout_factor;
  o.move_timeout_margin = c.move_timeout_margin;
  o.speed_tcp_mm_s = c.speed_tcp_mm_s;
  o.speed_ori_deg_s = c.speed_ori_deg_s;
  o.reconnect_attempts = c.reconnect_attempts;
  return o;
}

Eigen::Matrix3d psdRotationOf(const std::array<double, 3>& rpy) {
  return (Eigen::AngleAxisd(rpy[2] * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy[1] * kDegToRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy[0] * kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

HardwareBackend::HardwareBackend(const DaemonConfig& config)
    : config_(config),
      map_(config.daq.map_file.empty()
               ? throw ConfigError("daq.map_file",
                                   {"the hardware backend needs the PSD map (from `zerocal "
                                    "psd-map`): set daq.map_file"})
               : psd::loadPsdMap(config.daq.map_file)) {
  const Irc5Options o = irc5OptionsOf(config.controller);
  knowledge_.cell.robot = o.robot;
  knowledge_.cell.psd_rotation = psdRotationOf(config.session.psd_rpy_deg);
  const auto& t = config.session.target_mm;
  knowledge_.taught_centre_mm = Eigen::Vector3d(t[0], t[1], t[2]);
  knowledge_.psd_map = config.daq.map_file + ", fingerprint " + map_.fingerprint();
}

std::unique_ptr<ConnectedCell> HardwareBackend::connect() {
  Irc5Options o = irc5OptionsOf(config_.controller);
  o.host = config_.controller.host;
  o.port = config_.controller.port;
  return std::make_unique<HardwareCell>(std::move(o), config_.daq, map_);
}

}  // namespace zerocal::service
