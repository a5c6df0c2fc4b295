// A kind of acquisition board reading the PSD, as the rest of zerocal sees it: the section of the
// configuration it owns (daq.<kind>: which board, which inputs, how fast; its checks) and the
// readout it makes. The daemon's daq section holds only the kind's name, the PSD's map and its
// light threshold; everything about one board sits in its folder (drivers/usb1408fs: Measurement
// Computing's USB-1408FS), and one line of the kinds' list (zerocal/cell/kinds.h) names it.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "zerocal/cell/psd_reader.h"
#include "zerocal/psd/psd.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/settings/settings.h"

namespace zerocal {

// One DAQ kind's section of the configuration and what it makes.
class DaqSettings : public settings::KindSection {
 public:
  virtual std::unique_ptr<DaqSettings> clone() const = 0;
  // The readout, its board opened, turning averaged voltages into readings through `map` and
  // the light threshold of `psd` (the daq section's vendor-free part), stamped with `clock`.
  // Throws the board's LinkError when it cannot be opened.
  virtual std::unique_ptr<PsdReadout> readout(const psd::PsdMap& map, const psd::PsdConfig& psd,
                                              CellClock& clock) const = 0;
};

// A kind: the word of daq.kind (and its section's name), and its section's defaults.
struct DaqKind {
  std::string name;
  std::string description;  // "Measurement Computing USB-1408FS through zerocal's libusb driver"
  std::function<std::unique_ptr<DaqSettings>()> defaults;
};

}  // namespace zerocal
