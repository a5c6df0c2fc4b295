// The USB-1408FS's part of the PSD chain: which inputs carry the PSD's X, Y and SUM, and the
// averaged voltages read from them (one hardware-paced scan per reading, or a scan that never
// stops). psd::PsdMap turns those voltages into a reading (zerocal/psd/psd.h).
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

#include "zerocal/psd/psd.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::usb1408fs {

using psd::VoltageReading;

// Which inputs carry X, Y and SUM, and their ranges (the configuration's
// daq.usb-1408fs.channels).
struct PsdChannels {
  Channel x{0, InputMode::kDifferential, Range::kBip5V};
  Channel y{1, InputMode::kDifferential, Range::kBip5V};
  Channel sum{2, InputMode::kDifferential, Range::kBip5V};
};

// The board's part of the daq section (daq.usb-1408fs): which board, which inputs, how fast.
struct BoardSettings {
  std::string serial;  // USB serial-number string; empty = the first USB-1408FS found
  PsdChannels channels;
  double scan_rate_hz = 1000.0;   // scans per second (each scan converts x, y and sum once)
  int samples_per_reading = 100;  // scans averaged into one reading
};

// Averages a hardware-paced scan of the three PSD channels into readings of `block` samples per
// channel. Scan order is {x, y, sum} (PsdReader sets it up). Allocation-free once constructed;
// onScanData runs on the polling thread.
class BlockAverager : public ScanConsumer {
 public:
  // Throws std::invalid_argument if block is 0.
  explicit BlockAverager(std::size_t block);
  void onScanData(const ScanBlock& block) noexcept override;
  void onPacketsLost(std::uint32_t lost, std::uint16_t index) noexcept override;
  // The latest complete reading, once; false if none completed since the last call.
  bool take(VoltageReading& reading) noexcept;
  std::uint64_t blocksDiscarded() const noexcept { return discarded_; }

 private:
  void reset() noexcept;
  std::size_t block_;
  std::array<double, 3> sum_{}, sum2_{};
  std::array<std::size_t, 3> count_{};
  VoltageReading ready_;
  bool has_ready_ = false;
  std::uint64_t discarded_ = 0;
};

// One averaged reading, synchronously: a single-execution scan of `samples` scans of the three
// channels at `rate_hz` scans per second. Throws as Usb1408fs does.
VoltageReading readAveraged(Usb1408fs& daq, const PsdChannels& channels, std::size_t samples,
                            double rate_hz);

// The scan readAveraged() runs: {x, y, sum}, `samples` scans, single execution.
ScanConfig averagedScan(const PsdChannels& channels, std::size_t samples, double rate_hz);
// The same reading over a scan built once by averagedScan(): allocates nothing once the driver
// has run one scan of that shape (errors excepted). Throws as Usb1408fs does, and
// std::invalid_argument for a scan of 0 scans.
VoltageReading readAveraged(Usb1408fs& daq, const ScanConfig& scan);

// Continuous readings: a hardware-paced scan of the three channels that never stops, averaged in
// blocks, so a reading is ready every `samples / rate_hz` seconds without the command round trips
// of readAveraged(). Owns the scan while it lives; the Usb1408fs must outlive it.
class PsdStream {
 public:
  // Starts the scan. Throws as Usb1408fs::startScan.
  PsdStream(Usb1408fs& daq, const PsdChannels& channels, std::size_t samples, double rate_hz);
  ~PsdStream();
  PsdStream(const PsdStream&) = delete;
  PsdStream& operator=(const PsdStream&) = delete;

  // Waits up to `timeout` for the next complete reading; false if none came. Throws as
  // Usb1408fs::pollScan (the scan is then stopped).
  bool next(VoltageReading& reading, std::chrono::milliseconds timeout);
  std::uint64_t blocksDiscarded() const noexcept { return averager_.blocksDiscarded(); }

 private:
  Usb1408fs& daq_;
  BlockAverager averager_;
};

}  // namespace zerocal::usb1408fs
