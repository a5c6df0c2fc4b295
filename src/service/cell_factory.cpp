#include "zerocal/service/cell_factory.h"

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/servo/psd_reader.h"
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

}  // namespace

Robot robotOf(const ControllerConfig& c) {
  return c.robot == "builtin" ? builtinIrb1600() : loadRobot(c.robot);
}

Irc5Options irc5OptionsOf(const ControllerConfig& c, Irc5Options o) {
  o.robot = robotOf(c);
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

std::unique_ptr<ControllerConnection> makeControllerConnection(const ControllerConfig& config) {
  switch (config.kind) {
    case ControllerKind::kIrc5: {
      Irc5Options options = irc5OptionsOf(config);
      options.host = config.host;
      options.port = config.port;
      return std::make_unique<Irc5Client>(std::move(options));
    }
  }
  throw ConfigError("controller.kind", {"not a controller zerocal can drive"});
}

std::unique_ptr<PsdReadout> makePsdReadout(const DaqConfig& config, const psd::PsdMap& map,
                                           CellClock& clock) {
  switch (config.kind) {
    case DaqKind::kUsb1408fs:
      return std::make_unique<servo::Usb1408fsReadout>(
          [serial = config.serial] { return usb1408fs::LibusbTransport::open(serial); }, map, clock,
          readerOptionsOf(config));
  }
  throw ConfigError("daq.kind", {"not an acquisition board zerocal can read"});
}

}  // namespace zerocal::service
