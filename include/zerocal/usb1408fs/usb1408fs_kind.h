// The USB-1408FS as a DAQ kind (zerocal/cell/daq_kind.h): the daq.usb-1408fs section of the
// configuration (board serial, PSD inputs, scan rate, scans per reading), its checks, and the
// readout over libusb.
#pragma once

#include <memory>

#include "zerocal/cell/daq_kind.h"
#include "zerocal/usb1408fs/psd_chain.h"

namespace zerocal::usb1408fs {

class Usb1408fsSettings final : public DaqSettings {
 public:
  BoardSettings board;

  std::unique_ptr<DaqSettings> clone() const override {
    return std::make_unique<Usb1408fsSettings>(*this);
  }
  void declare(const std::string& prefix, settings::Fields& fields) override;
  void check(const std::string& prefix, bool real_cell, settings::Checker& check) const override;
  std::unique_ptr<PsdReadout> readout(const psd::PsdMap& map, const psd::PsdConfig& psd,
                                      CellClock& clock) const override;
};

// The kind "usb-1408fs".
DaqKind daqKind();

// The board settings among a configuration's DAQ sections (for `zerocal-lab psd`, which reads this
// board only). Throws ConfigError when the configuration has no usb-1408fs section.
const BoardSettings& boardSettingsOf(const settings::KindSections<DaqSettings>& sections);

}  // namespace zerocal::usb1408fs
