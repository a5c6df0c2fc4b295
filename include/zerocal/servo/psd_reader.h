// The seam between the servo and the PSD: one averaged, mapped reading per call, stamped with the
// cell's clock. ChainPsdReader implements it over the real measurement chain (USB-1408FS ->
// readAveraged -> PsdMap); tests may implement it directly.
#pragma once

#include <chrono>
#include <cstddef>

#include "zerocal/psd/psd.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::servo {

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

// One PSD reading in the PSD frame (origin at the detector centre), millimetres.
struct PsdReading {
  double u_mm = 0, v_mm = 0;
  double u_se_mm = 0, v_se_mm = 0;  // standard errors of the averaged reading
  double sum_v = 0;
  // SUM above the detector's threshold: some light is on the detector.
  bool spot_present = false;
  // Present and inside the zone the map was fitted on. When false but present, u and v are only
  // a coarse estimate (saturating voltages over the centre slope): right in sign, too small.
  bool in_valid_zone = false;
  double time_s = 0;  // cell clock at the end of the reading
};

class PsdReader {
 public:
  virtual ~PsdReader() = default;
  // Blocks for one reading. May throw the DAQ's errors (zerocal/usb1408fs/errors.h).
  virtual PsdReading read() = 0;
};

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

}  // namespace zerocal::servo
