// The PSD reader of the USB-1408FS measurement chain (USB-1408FS -> readAveraged -> PsdMap),
// behind the vendor-neutral PsdReader seam (zerocal/cell/psd_reader.h).
#pragma once

#include <chrono>
#include <cstddef>

#include "zerocal/cell/psd_reader.h"
#include "zerocal/psd/psd.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::servo {

struct ChainPsdReaderOptions {
  psd::PsdChannels channels;
  std::size_t samples = 64;                            // per channel, averaged into one reading
  double rate_hz = 16000;                              // scans per second
  double on_threshold_v = 0.5, off_threshold_v = 0.4;  // SpotDetector hysteresis on SUM
  double coarse_v_per_mm = 5.0;  // centre slope, for the coarse estimate outside the zone
};

// The real chain. `daq` and `clock` must outlive the reader. Each read() runs one
// single-execution scan (psd::readAveraged), so a reading holds only samples converted after
// read() was called, never light from before the last move ended. The scan is built once here;
// read() allocates nothing once the first reading has sized the driver's buffers.
class ChainPsdReader final : public PsdReader {
 public:
  ChainPsdReader(usb1408fs::Usb1408fs& daq, psd::PsdMap map, CellClock& clock,
                 ChainPsdReaderOptions options = {});
  PsdReading read() override;

 private:
  usb1408fs::Usb1408fs& daq_;
  psd::PsdMap map_;
  CellClock& clock_;
  ChainPsdReaderOptions options_;
  usb1408fs::ScanConfig scan_;
  psd::SpotDetector detector_;
};

// The USB-1408FS readout a cell owns: the board (opened by `opener`, libusb's or the simulated
// board's) and the chain reading it.
class Usb1408fsReadout final : public PsdReadout {
 public:
  // Opens the board. Throws as Usb1408fs.
  Usb1408fsReadout(usb1408fs::Usb1408fs::Opener opener, psd::PsdMap map, CellClock& clock,
                   ChainPsdReaderOptions options = {})
      : daq_(std::move(opener)), chain_(daq_, std::move(map), clock, std::move(options)) {}
  PsdReading read() override { return chain_.read(); }
  void reopen() override { daq_.reopen(); }

 private:
  usb1408fs::Usb1408fs daq_;
  ChainPsdReader chain_;
};

}  // namespace zerocal::servo
