// The PSD measurement chain: samples of the conditioning board's X, Y and SUM voltages (read by
// the USB-1408FS) -> one averaged reading with its standard error -> spot present or not -> spot
// position in millimetres through a map fitted from a stage sweep, marked valid or not.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include "zerocal/psd/spot.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::psd {

// Which inputs carry X, Y and SUM, and their ranges (from the configuration).
struct PsdChannels {
  usb1408fs::Channel x{0, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V};
  usb1408fs::Channel y{1, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V};
  usb1408fs::Channel sum{2, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V};
};

// Block means in volts and their standard errors (sample std / sqrt(n)), in volts.
struct VoltageReading {
  double x = 0, y = 0, sum = 0;
  double x_se = 0, y_se = 0, sum_se = 0;
  std::size_t samples = 0;  // per channel
};

// Averages a hardware-paced scan of the three PSD channels into readings of `block` samples per
// channel. Scan order is {x, y, sum} (PsdReader sets it up). Allocation-free once constructed;
// onScanData runs on the polling thread.
class BlockAverager : public usb1408fs::ScanConsumer {
 public:
  // Throws std::invalid_argument if block is 0.
  explicit BlockAverager(std::size_t block);
  void onScanData(const usb1408fs::ScanBlock& block) noexcept override;
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
VoltageReading readAveraged(usb1408fs::Usb1408fs& daq, const PsdChannels& channels,
                            std::size_t samples, double rate_hz);

// The scan readAveraged() runs: {x, y, sum}, `samples` scans, single execution.
usb1408fs::ScanConfig averagedScan(const PsdChannels& channels, std::size_t samples,
                                   double rate_hz);
// The same reading over a scan built once by averagedScan(): allocates nothing once the driver
// has run one scan of that shape (errors excepted). Throws as Usb1408fs does, and
// std::invalid_argument for a scan of 0 scans.
VoltageReading readAveraged(usb1408fs::Usb1408fs& daq, const usb1408fs::ScanConfig& scan);

// Continuous readings: a hardware-paced scan of the three channels that never stops, averaged in
// blocks, so a reading is ready every `samples / rate_hz` seconds without the command round trips
// of readAveraged(). Owns the scan while it lives; the Usb1408fs must outlive it.
class PsdStream {
 public:
  // Starts the scan. Throws as Usb1408fs::startScan.
  PsdStream(usb1408fs::Usb1408fs& daq, const PsdChannels& channels, std::size_t samples,
            double rate_hz);
  ~PsdStream();
  PsdStream(const PsdStream&) = delete;
  PsdStream& operator=(const PsdStream&) = delete;

  // Waits up to `timeout` for the next complete reading; false if none came. Throws as
  // Usb1408fs::pollScan (the scan is then stopped).
  bool next(VoltageReading& reading, std::chrono::milliseconds timeout);
  std::uint64_t blocksDiscarded() const noexcept { return averager_.blocksDiscarded(); }

 private:
  usb1408fs::Usb1408fs& daq_;
  BlockAverager averager_;
};

// Spot present when SUM exceeds a threshold (volts); hysteresis keeps a spot on the rim from
// flickering.
class SpotDetector {
 public:
  explicit SpotDetector(double on_threshold_v = 0.5, double off_threshold_v = 0.4);
  bool update(const VoltageReading& reading) noexcept;
  bool present() const noexcept { return present_; }

 private:
  double on_, off_;
  bool present_ = false;
};

// One point of a sweep: a known stage position (mm) and the averaged voltages there.
struct SweepPoint {
  PsdSpot spot;  // where the stage put the spot
  double x_v = 0, y_v = 0, sum_v = 0;
};

// Reads a sweep as CSV: a header line naming the columns u_mm, v_mm, x_v, y_v, sum_v (any order,
// other columns ignored), then one row per stage position. Throws zerocal::InputError naming
// every bad line.
std::vector<SweepPoint> readSweepCsv(std::istream& in, const std::string& origin);
// Writes a sweep in the form readSweepCsv reads (header u_mm,v_mm,x_v,y_v,sum_v).
void writeSweepCsv(std::ostream& out, const std::vector<SweepPoint>& sweep);

struct MapFitOptions {
  int degree = 7;                   // total degree of the polynomial in (X, Y)
  double zone_half_width_mm = 0.6;  // sweep points with |u|,|v| within this are fitted
  double min_sum_v = 0.5;           // points with less light are ignored
};

struct MapFitReport {
  std::size_t points_used = 0;
  double rms_residual_mm = 0, max_residual_mm = 0;
  double u_min = 0, u_max = 0, v_min = 0, v_max = 0;  // valid zone (mm)
};

struct SpotPosition {
  PsdSpot spot;
  PsdSpot se;            // from the voltage standard errors through the map
  bool present = false;  // enough light (SpotDetector threshold)
  bool valid = false;    // present and inside the zone the map was fitted on
};

// Voltages -> millimetres: u = sum a_ij X^i Y^j, v = sum b_ij X^i Y^j over i + j <= degree, with
// X, Y scaled to volts / 5.
class PsdMap {
 public:
  // Least-squares fit over the sweep points inside the zone. Throws zerocal::InputError if the
  // sweep has too few usable points, std::invalid_argument for a degree outside 1..12.
  static PsdMap fit(const std::vector<SweepPoint>& sweep, const MapFitOptions& options,
                    MapFitReport* report = nullptr);

  SpotPosition apply(const VoltageReading& reading) const;
  // Plain-text form for the configuration, and back (throws zerocal::InputError).
  std::string serialize() const;
  static PsdMap parse(const std::string& text);
  // 16 hex digits (FNV-1a of serialize()) that name this map in a result: two results with the
  // same fingerprint were read through the same map, whatever its file was called.
  std::string fingerprint() const;

  // The parts, so that the configuration can store the map in its own format (psd_config.h).
  // fromParts throws std::invalid_argument when the parts do not make a map: degree outside
  // 1..12, coefficient counts other than termCount(degree), an empty or non-finite zone.
  static std::size_t termCount(int degree);
  static PsdMap fromParts(int degree, std::vector<double> u_coeff, std::vector<double> v_coeff,
                          const std::array<double, 4>& zone_mm, double min_sum_v);
  int degree() const noexcept { return degree_; }
  const std::vector<double>& uCoefficients() const noexcept { return u_coeff_; }
  const std::vector<double>& vCoefficients() const noexcept { return v_coeff_; }
  // {u_min, u_max, v_min, v_max} in mm: where the map was fitted, hence valid.
  std::array<double, 4> zone() const noexcept { return {u_min_, u_max_, v_min_, v_max_}; }
  double minSumV() const noexcept { return min_sum_v_; }

 private:
  void evaluate(double x, double y, double& u, double& v, double& du_dx, double& du_dy,
                double& dv_dx, double& dv_dy) const;
  int degree_ = 0;
  std::vector<double> u_coeff_, v_coeff_;
  double u_min_ = 0, u_max_ = 0, v_min_ = 0, v_max_ = 0;
  double min_sum_v_ = 0.5;
};

}  // namespace zerocal::psd
