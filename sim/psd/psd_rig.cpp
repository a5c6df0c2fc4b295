#include "zerocal/sim/psd_rig.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace zerocal::sim {
namespace {

PsdWiring wiringFor(const usb1408fs::PsdChannels& channels) {
  PsdWiring wiring;
  wiring.x = channels.x;
  wiring.y = channels.y;
  wiring.sum = channels.sum;
  return wiring;
}

PsdModelOptions withSeed(std::uint32_t seed) {
  PsdModelOptions options;
  options.seed = seed;
  return options;
}

}  // namespace

SimulatedPsdRig::SimulatedPsdRig(std::uint32_t seed, const usb1408fs::PsdChannels& channels)
    : channels_(channels), psd_(withSeed(seed)) {
  board_.setAnalogSource(psdAnalogSource(
      psd_, [this](double) { return spot_; }, wiringFor(channels)));
  daq_ = std::make_unique<usb1408fs::Usb1408fs>(FakeTransport::opener(board_));
}

std::vector<psd::SweepPoint> simulateSweep(SimulatedPsdRig& rig, const SweepOptions& options) {
  if (!(options.step_mm > 0) || !(options.extent_mm > 0)) {
    throw std::invalid_argument("the sweep step and extent must be positive");
  }
  // The small tolerance keeps +extent on the grid when 2 extent / step is whole.
  const double span = 2 * options.extent_mm / options.step_mm;
  if (span > 400) {
    throw std::invalid_argument("the sweep would have more than 401 positions per axis");
  }
  const int n = static_cast<int>(std::floor(span + 1e-9));
  std::vector<psd::SweepPoint> sweep;
  sweep.reserve(static_cast<std::size_t>((n + 1) * (n + 1)));
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const PsdSpot p{-options.extent_mm + j * options.step_mm,
                      -options.extent_mm + i * options.step_mm};
      rig.setSpot(p);
      const psd::VoltageReading r =
          usb1408fs::readAveraged(rig.daq(), rig.channels(), options.samples, options.rate_hz);
      sweep.push_back({p, r.x, r.y, r.sum});
    }
  }
  return sweep;
}

}  // namespace zerocal::sim
