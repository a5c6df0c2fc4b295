#include "zerocal/servo/psd_reader.h"

#include <thread>
#include <utility>

namespace zerocal {

void CellClock::waitS(double seconds) noexcept {
  if (seconds > 0) std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
}

double SteadyCellClock::nowS() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

}  // namespace zerocal

namespace zerocal::servo {

ChainPsdReader::ChainPsdReader(usb1408fs::Usb1408fs& daq, psd::PsdMap map, CellClock& clock,
                               ChainPsdReaderOptions options)
    : daq_(daq),
      map_(std::move(map)),
      clock_(clock),
      options_(options),
      scan_(psd::averagedScan(options.channels, options.samples, options.rate_hz)),
      detector_(options.on_threshold_v, options.off_threshold_v) {}

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
    r.spot = {v.x / options_.coarse_v_per_mm, v.y / options_.coarse_v_per_mm};
    r.se = {v.x_se / options_.coarse_v_per_mm, v.y_se / options_.coarse_v_per_mm};
  }
  r.time_s = clock_.nowS();
  return r;
}

}  // namespace zerocal::servo
