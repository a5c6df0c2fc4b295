#include "zerocal/sim/simulated_cell.h"

#include <cmath>
#include <optional>
#include <utility>
#include <vector>

namespace zerocal::sim {
namespace {

// The paper's mapping: a probe stage moves the spot over a grid, the averaged voltages are kept.
std::vector<psd::SweepPoint> stageSweep(PsdModel& psd, double half_width, double step) {
  std::vector<psd::SweepPoint> sweep;
  const int n = static_cast<int>(std::lround(2 * half_width / step));
  constexpr int kSamples = 64;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const PsdSpot p{-half_width + i * step, -half_width + j * step};
      psd::SweepPoint s{p, 0, 0, 0};
      for (int k = 0; k < kSamples; ++k) {
        const PsdVoltages v = psd.measure(p);
        s.x_v += v.x / kSamples;
        s.y_v += v.y / kSamples;
        s.sum_v += v.sum / kSamples;
      }
      sweep.push_back(s);
    }
  }
  return sweep;
}

}  // namespace

SimulatedCellOptions seededCellOptions(std::uint64_t seed, WorldKind kind) {
  SimulatedCellOptions o;
  o.world = randomWorld(seed, kind);
  o.controller_seed = seed;
  o.psd.seed = static_cast<std::uint32_t>(seed) + 100;
  return o;
}

psd::PsdMap simulatedPsdMap(PsdModelOptions psd, double half_width_mm, double step_mm) {
  // The sweep uses its own copy of the detector (another noise stream), as the mapping happened
  // on the bench long before this session.
  psd.seed += 1;
  PsdModel bench_psd(psd);
  return psd::PsdMap::fit(stageSweep(bench_psd, half_width_mm, step_mm), psd::MapFitOptions{});
}

namespace {

SimControllerOptions controllerOptions(const SimulatedCellOptions& o) {
  SimControllerOptions c;
  c.world = o.world;
  c.seed = o.controller_seed;
  c.pace = o.pace;
  c.warm_s = o.warm_s;
  c.motion = o.motion;
  c.search.wired = o.search_signal;
  c.search.psd = o.psd;  // the comparator watches this cell's detector
  c.start_joints = o.start_joints;
  return c;
}

}  // namespace

SimulatedCell::SimulatedCell(SimulatedCellOptions options)
    : options_(std::move(options)),
      controller_(std::make_unique<SimController>(controllerOptions(options_))),
      psd_(options_.psd),
      board_(options_.board_seed),
      map_(simulatedPsdMap(options_.psd, options_.sweep_half_width_mm, options_.sweep_step_mm)) {
  SimController* controller = controller_.get();
  board_.setAnalogSource(psdAnalogSource(psd_, [controller](double) -> std::optional<PsdSpot> {
    const std::optional<BeamHit> hit = controller->beamHitNow();
    if (!hit) return std::nullopt;
    return hit->spot;
  }));
  controller_->start();
}

SimulatedCell::~SimulatedCell() { controller_->stop(); }

Irc5Options SimulatedCell::clientOptions() const {
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = controller_->port();
  o.robot = controller_->world().robot;
  o.reconnect_attempts = 3;
  o.backoff_initial = std::chrono::milliseconds(10);
  return o;
}

void SimulatedCell::reseedNoise(std::uint64_t seed) {
  controller_->reseedNoise(seed);
  psd_.reseed(static_cast<std::uint32_t>(seed) + 100);
}

double SimulatedCell::nowS() noexcept {
  return controller_->simTimeS() + std::chrono::duration<double>(board_.now()).count() + waited_s_;
}

void SimulatedCell::waitS(double seconds) noexcept {
  if (seconds > 0) waited_s_ += seconds;
}

SimulatedReadout simulatedReadout() {
  SimulatedReadout r;
  r.board.samples_per_reading = 64;
  r.board.scan_rate_hz = 16000;
  r.psd.sum_threshold_v = 0.5;  // and 0.4 to lose a spot (psd::PsdConfig::sumOffThresholdV)
  return r;
}

}  // namespace zerocal::sim
