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
                               const psd::PsdConfig& config)
    : daq_(daq),
      map_(std::move(map)),
      clock_(clock),
      scan_(psd::averagedScan(config.channels, static_cast<std::size_t>(config.samples_per_reading),
                              config.scan_rate_hz)),
      detector_(config.sum_threshold_v, config.sumOffThresholdV()) {}

PsdReading ChainPsdReader::read() {
  // A scan per reading rather than a continuous one (psd::PsdStream): samples queued while the
  // robot moved carry no time, so a stream would have to be drained at every read to keep them
  // out, and nothing polls it during a move of seconds, when the board's FIFO would overrun. The
  // cost is three commands per reading (ALOAD_QUEUE, AIN_SCAN, AIN_STOP).
  const psd::VoltageReading v = psd::readAveraged(daq_, scan_);
  const bool present = detector_.update(v);
  const psd::SpotPosition p = map_.apply(v);
  PsdReading r;
  r.sum_v = v.sum;
  r.spot_present = present;
  r.in_valid_zone = present && p.valid;
  if (r.in_valid_zone) {
    r.spot = p.spot;
    r.se = p.se;
  } else {
    // The map extrapolates wildly outside its zone; the saturating voltages over the centre slope
    // still point the right way, which is all the servo needs to get back into the zone.
    r.spot = {v.x / kCoarseVoltsPerMm, v.y / kCoarseVoltsPerMm};
    r.se = {v.x_se / kCoarseVoltsPerMm, v.y_se / kCoarseVoltsPerMm};
  }
  r.time_s = clock_.nowS();
  return r;
}

}  // namespace zerocal::usb1408fs
