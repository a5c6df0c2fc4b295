// The PSD reader of the USB-1408FS measurement chain (USB-1408FS -> readAveraged -> PsdMap),
// behind the vendor-neutral PsdReader seam (zerocal/cell/psd_reader.h).
#pragma once

#include <chrono>
#include <cstddef>

#include "zerocal/cell/psd_reader.h"
#include "zerocal/psd/psd.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/usb1408fs/psd_chain.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::usb1408fs {

// The real chain. `daq` and `clock` must outlive the reader. Each read() runs one
// single-execution scan (readAveraged), so a reading holds only samples converted after
// read() was called, never light from before the last move ended. The scan is built once here;
// read() allocates nothing once the first reading has sized the driver's buffers.
class ChainPsdReader final : public PsdReader {
 public:
  // `board`: the channels, scans per reading and their rate; `psd`: the SUM threshold.
  ChainPsdReader(Usb1408fs& daq, psd::PsdMap map, CellClock& clock, const BoardSettings& board,
                 const psd::PsdConfig& psd);
  PsdReading read() override;

 private:
  Usb1408fs& daq_;
  psd::PsdMap map_;
  CellClock& clock_;
  ScanConfig scan_;
  psd::SpotDetector detector_;
};

// The USB-1408FS readout a cell owns: the board (opened by `opener`, libusb's or the simulated
// board's) and the chain reading it.
class Usb1408fsReadout final : public PsdReadout {
 public:
  // Opens the board. Throws as Usb1408fs.
  Usb1408fsReadout(Usb1408fs::Opener opener, psd::PsdMap map, CellClock& clock,
                   const BoardSettings& board, const psd::PsdConfig& psd)
      : daq_(std::move(opener)), chain_(daq_, std::move(map), clock, board, psd) {}
  PsdReading read() override { return chain_.read(); }
  void reopen() override { daq_.reopen(); }

 private:
  Usb1408fs daq_;
  ChainPsdReader chain_;
};

}  // namespace zerocal::usb1408fs
