#include "zerocal/sim/psd_model.h"

#include <algorithm>
#include <cmath>
#include <memory>

namespace zerocal::sim {
namespace {

bool sameChannel(const usb1408fs::Channel& a, const usb1408fs::Channel& b) {
  return a.number == b.number && a.mode == b.mode;
}

}  // namespace

PsdModel::PsdModel(PsdModelOptions options)
    : options_(options), rng_(options.seed), noise_(0.0, options.noise_rms_v) {
  // For a Gaussian of standard deviation s on an infinite split detector the normalised
  // difference is erf(u / (sqrt(2) s)), of slope sqrt(2/pi) / s at the centre.
  const double sigma = options_.spot_diameter_mm / 4.0;
  gain_v_ = options_.sensitivity_v_per_mm * sigma / std::sqrt(2.0 / M_PI);
  // The gaps and the dark term lower the slope a little; measure it and correct the gain.
  const double h = 1e-3;
  const double slope = (ideal(PsdSpot{h, 0}).x - ideal(PsdSpot{-h, 0}).x) / (2 * h);
  gain_v_ *= options_.sensitivity_v_per_mm / slope;
}

PsdVoltages PsdModel::ideal(const std::optional<PsdSpot>& spot) const {
  if (!spot) return {0.0, 0.0, 0.0};
  const double s = std::sqrt(2.0) * options_.spot_diameter_mm / 4.0;  // sqrt(2) sigma
  const double radius = options_.active_diameter_mm / 2.0;
  const double g = options_.gap_mm / 2.0;
  // Separable model: along each axis the spot's light is split at the gaps and clipped at the
  // chord of the disk through the spot (the chord is taken no shorter than at 0.9 R so that a
  // spot just off the rim still sends its tail in). Exact for the central region, smooth in the
  // spot position (a map fitted to it must not see integration steps), and it never produces
  // negative light.
  auto chord = [&](double other) {
    const double c = std::min(std::abs(other), 0.9 * radius);
    return std::sqrt(radius * radius - c * c);
  };
  auto between = [&](double lo, double hi, double c) {
    return hi <= lo ? 0.0 : 0.5 * (std::erf((hi - c) / s) - std::erf((lo - c) / s));
  };
  const double ru = chord(spot->v_mm), rv = chord(spot->u_mm);
  const double r = between(g, ru, spot->u_mm), l = between(-ru, -g, spot->u_mm);
  const double t = between(g, rv, spot->v_mm), b = between(-rv, -g, spot->v_mm);
  const double right = r * (t + b), left = l * (t + b), top = t * (r + l), bottom = b * (r + l);
  const double on = (r + l) * (t + b);
  const double norm = on + options_.dark_fraction;
  return {gain_v_ * (right - left) / norm, gain_v_ * (top - bottom) / norm,
          options_.full_sum_v * on};
}

PsdVoltages PsdModel::measure(const std::optional<PsdSpot>& spot) {
  PsdVoltages v = ideal(spot);
  v.x += noise_(rng_);
  v.y += noise_(rng_);
  v.sum += noise_(rng_);
  return v;
}

void PsdModel::reseed(std::uint32_t seed) {
  options_.seed = seed;
  rng_.seed(seed);
  noise_.reset();  // a pair half drawn from the old stream is not the new stream's
}

Usb1408fsModel::AnalogSource psdAnalogSource(
    PsdModel& psd, std::function<std::optional<PsdSpot>(double t)> spot_at, PsdWiring wiring) {
  struct Cache {
    double t = std::nan("");
    PsdVoltages v;
  };
  auto cache = std::make_shared<Cache>();
  return
      [&psd, spot_at = std::move(spot_at), wiring, cache](const usb1408fs::Channel& ch, double t) {
        // One physical state per instant: the three channels of a scan share it.
        if (!(cache->t == t)) {
          cache->t = t;
          cache->v = psd.measure(spot_at(t));
        }
        if (sameChannel(ch, wiring.x)) return cache->v.x;
        if (sameChannel(ch, wiring.y)) return cache->v.y;
        if (sameChannel(ch, wiring.sum)) return cache->v.sum;
        return 0.0;
      };
}

}  // namespace zerocal::sim
