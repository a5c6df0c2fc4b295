#include "zerocal/usb1408fs/psd_chain.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "zerocal/usb1408fs/errors.h"

namespace zerocal::usb1408fs {
namespace {

using namespace std::chrono_literals;

double meanOf(double sum, std::size_t n) { return n ? sum / static_cast<double>(n) : 0.0; }

double standardError(double sum, double sum2, std::size_t n) {
  if (n < 2) return 0.0;
  const double dn = static_cast<double>(n);
  const double var = std::max(0.0, (sum2 - sum * sum / dn) / (dn - 1.0));
  return std::sqrt(var / dn);
}

}  // namespace

BlockAverager::BlockAverager(std::size_t block) : block_(block) {
  if (block_ == 0) throw std::invalid_argument("PSD averaging block must be at least 1 sample");
}

void BlockAverager::reset() noexcept {
  sum_ = {};
  sum2_ = {};
  count_ = {};
}

void BlockAverager::onScanData(const ScanBlock& block) noexcept {
  for (std::size_t i = 0; i < block.count; ++i) {
    const std::size_t c = (block.first_channel + i) % 3;
    const double v = block.volts[i];
    sum_[c] += v;
    sum2_[c] += v * v;
    ++count_[c];
    // SUM is last in the scan: when its count reaches the block, X and Y have as many.
    if (c == 2 && count_[2] == block_) {
      VoltageReading r;
      r.samples = block_;
      r.x = meanOf(sum_[0], count_[0]);
      r.y = meanOf(sum_[1], count_[1]);
      r.sum = meanOf(sum_[2], count_[2]);
      r.x_se = standardError(sum_[0], sum2_[0], count_[0]);
      r.y_se = standardError(sum_[1], sum2_[1], count_[1]);
      r.sum_se = standardError(sum_[2], sum2_[2], count_[2]);
      ready_ = r;
      has_ready_ = true;
      reset();
    }
  }
}

void BlockAverager::onPacketsLost(std::uint32_t, std::uint16_t) noexcept {
  // A block with a hole would mix times; drop it rather than average around the hole.
  ++discarded_;
  reset();
}

bool BlockAverager::take(VoltageReading& reading) noexcept {
  if (!has_ready_) return false;
  reading = ready_;
  has_ready_ = false;
  return true;
}

ScanConfig averagedScan(const PsdChannels& channels, std::size_t samples, double rate_hz) {
  ScanConfig config;
  config.channels = {channels.x, channels.y, channels.sum};
  config.rate_hz = rate_hz;
  config.scans = static_cast<std::uint32_t>(samples);
  return config;
}

VoltageReading readAveraged(Usb1408fs& daq, const PsdChannels& channels, std::size_t samples,
                            double rate_hz) {
  return readAveraged(daq, averagedScan(channels, samples, rate_hz));
}

VoltageReading readAveraged(Usb1408fs& daq, const ScanConfig& scan) {
  BlockAverager averager(scan.scans);
  daq.startScan(scan, averager);
  try {
    while (!daq.scanComplete()) daq.pollScan(5ms);
  } catch (...) {
    daq.stopScan();
    throw;
  }
  daq.stopScan();
  VoltageReading reading;
  if (!averager.take(reading)) {
    throw ProtocolError("the PSD reading lost " + std::to_string(daq.scanStats().lost_packets) +
                        " USB packets; it was discarded");
  }
  return reading;
}

PsdStream::PsdStream(Usb1408fs& daq, const PsdChannels& channels, std::size_t samples,
                     double rate_hz)
    : daq_(daq), averager_(samples) {
  ScanConfig config;
  config.channels = {channels.x, channels.y, channels.sum};
  config.rate_hz = rate_hz;
  config.scans = 0;
  daq_.startScan(config, averager_);
}

PsdStream::~PsdStream() { daq_.stopScan(); }

bool PsdStream::next(VoltageReading& reading, std::chrono::milliseconds timeout) {
  if (averager_.take(reading)) return true;
  // pollScan returns as soon as packets arrive; keep polling until a block completes or the
  // caller's time is used up.
  auto left = timeout;
  const auto step = std::min(timeout, std::chrono::milliseconds(2));
  while (left.count() > 0) {
    // Only empty polls use up the caller's time: a poll that brought packets returned early.
    if (daq_.pollScan(step) == 0) left -= step;
    if (averager_.take(reading)) return true;
  }
  return false;
}

}  // namespace zerocal::usb1408fs
