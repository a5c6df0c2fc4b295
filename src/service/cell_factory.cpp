#include "zerocal/service/cell_factory.h"

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/servo/psd_reader.h"
#include "zerocal/usb1408fs/libusb_transport.h"

namespace zerocal::service {
namespace {

servo::ChainPsdReaderOptions readerOptionsOf(const psd::PsdConfig& daq) {
  servo::ChainPsdReaderOptions o;
  o.channels = daq.channels;
  o.samples = static_cast<std::size_t>(daq.samples_per_reading);
  o.rate_hz = daq.scan_rate_hz;
  o.on_threshold_v = daq.sum_threshold_v;
  o.off_threshold_v = daq.sumOffThresholdV();
  return o;
}

}  // namespace

Robot robotOf(const ControllerConfig& c) {
  return c.robot == "builtin" ? builtinIrb1600() : loadRobot(c.robot);
}

Irc5Options irc5OptionsOf(const ControllerConfig& c) {
  Irc5Options o = c.irc5;
  o.robot = robotOf(c);
  return o;
}

std::unique_ptr<ControllerConnection> makeControllerConnection(const ControllerConfig& config) {
  switch (config.kind) {
    case ControllerKind::kIrc5:
      return std::make_unique<Irc5Client>(irc5OptionsOf(config));
  }
  throw ConfigError("controller.kind", {"not a controller zerocal can drive"});
}

std::unique_ptr<PsdReadout> makePsdReadout(const psd::PsdConfig& config, const psd::PsdMap& map,
                                           CellClock& clock) {
  switch (config.kind) {
    case psd::DaqKind::kUsb1408fs:
      return std::make_unique<servo::Usb1408fsReadout>(
          [serial = config.serial] { return usb1408fs::LibusbTransport::open(serial); }, map, clock,
          readerOptionsOf(config));
  }
  throw ConfigError("daq.kind", {"not an acquisition board zerocal can read"});
}

}  // namespace zerocal::service
