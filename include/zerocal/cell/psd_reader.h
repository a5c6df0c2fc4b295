// The seam between a session and the PSD, whatever reads it: one averaged, mapped reading per
// call, stamped with the cell's clock; and the cell's clock itself. ChainPsdReader
// (zerocal/usb1408fs/psd_readout.h) implements the reader over the USB-1408FS chain; tests and the
// simulated cell implement them directly.
#pragma once

#include <chrono>

#include "zerocal/psd/spot.h"

namespace zerocal {

// The cell's time in seconds. On a real cell a steady clock; on the simulated cell the simulated
// time of the controller plus the board, so a servo run is deterministic and costs no wall time.
class CellClock {
 public:
  virtual ~CellClock() = default;
  virtual double nowS() noexcept = 0;
  // Lets `seconds` of cell time pass with the robot at rest (settling, back-off). The default
  // sleeps on the calling thread (no allocation, no lock); a simulated cell advances its clock.
  virtual void waitS(double seconds) noexcept;
};

class SteadyCellClock final : public CellClock {
 public:
  double nowS() noexcept override;

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

class PsdReader {
 public:
  virtual ~PsdReader() = default;
  // Blocks for one reading. May throw a LinkError (zerocal/cell/link_error.h) of the kind that
  // says whether reopening the readout may help.
  virtual PsdReading read() = 0;
};

// A PSD reader with its device's life: what a connected cell owns. The cell factory
// (zerocal/service/cell_factory.h) makes one per daq.kind.
class PsdReadout : public PsdReader {
 public:
  // Closes and opens the readout again (after an unplug); throws the device's error.
  virtual void reopen() = 0;
};

}  // namespace zerocal
