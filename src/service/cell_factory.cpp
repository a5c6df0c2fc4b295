#include "zerocal/service/cell_factory.h"

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/usb1408fs/libusb_transport.h"
#include "zerocal/usb1408fs/psd_readout.h"

namespace zerocal::service {

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
      return std::make_unique<usb1408fs::Usb1408fsReadout>(
          [serial = config.serial] { return usb1408fs::LibusbTransport::open(serial); }, map, clock,
          config);
  }
  throw ConfigError("daq.kind", {"not an acquisition board zerocal can read"});
}

}  // namespace zerocal::service
