#include "zerocal/usb1408fs/psd_readout.h"

#include <utility>

namespace zerocal::usb1408fs {
namespace {

// Outside the map's zone the spot is estimated from the voltages over the PSD's X and Y slope at
// its centre (5 V/mm for the detector and amplifier the map was made with; psd::PsdMap's zone
// excludes the saturating rim where this is coarse).
constexpr double kCoarseVoltsPerMm = 5.0;

}  // namespace

ChainPsdReader::ChainPsdReader(Usb1408fs& daq, psd::PsdMap map, CellClock& clock,
                               const BoardSettings& board, const psd::PsdConfig& psd)
    : daq_(daq),
      map_(std::move(map)),
      clock_(clock),
      scan_(averagedScan(board.channels, static_cast<std::size_t>(board.samples_per_reading),
                         board.scan_rate_hz)),
      detector_(psd.sum_threshold_v, psd.sumOffThresholdV()) {}

PsdReading ChainPsdReader::read() {
  // A scan per reading rather than a continuous one (PsdStream): samples queued while the
  // robot moved carry no time, so a stream would have to be drained at every read to keep them
  // out, and nothing polls it during a move of seconds, when the board's FIFO would overrun. The
  // cost is three commands per reading (ALOAD_QUEUE, AIN_SCAN, AIN_STOP).
  const psd::VoltageReading v = readAveraged(daq_, scan_);
  const bool present = detector_.update(v);
  PsdReading r = map_.apply(v);
  // The detector's hysteresis decides presence, not the map's own light floor.
  r.spot_present = present;
  r.in_valid_zone = present && r.in_valid_zone;
  if (!r.in_valid_zone) {
    // The map extrapolates wildly outside its zone; the saturating voltages over the centre slope
    // still point the right way, which is all the servo needs to get back into the zone.
    r.spot = {v.x / kCoarseVoltsPerMm, v.y / kCoarseVoltsPerMm};
    r.se = {v.x_se / kCoarseVoltsPerMm, v.y_se / kCoarseVoltsPerMm};
  }
  r.time_s = clock_.nowS();
  return r;
}

}  // namespace zerocal::usb1408fs
