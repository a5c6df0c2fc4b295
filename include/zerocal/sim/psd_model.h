// The simulated position-sensitive detector and its signal-conditioning board: where the laser
// spot sits on the detector (u, v in mm, PSD frame, origin at the centre) to the board's X, Y and
// SUM voltages.
//
// Physics: a segmented (quadrant) photodiode, 10 mm diameter active disk with 0.1 mm gaps between
// quadrants, lit by a Gaussian spot of 2.5 mm (1/e^2) diameter. The board outputs the normalised
// differences X = G (right - left) / (total + dark), Y = G (top - bottom) / (total + dark) and
// SUM proportional to the light on the detector. The normalised difference follows erf(), nearly
// linear at ~5 V/mm within +-0.6 mm and saturating beyond; as the spot leaves the disk SUM falls
// to ~0 and X, Y relax towards 0. Additive Gaussian noise of ~0.005 V rms (about +-0.01 V) from a
// seeded generator.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <random>

#include "zerocal/psd/spot.h"
#include "zerocal/sim/usb1408fs_model.h"

namespace zerocal::sim {

struct PsdVoltages {
  double x = 0.0;    // V
  double y = 0.0;    // V
  double sum = 0.0;  // V
};

struct PsdModelOptions {
  double active_diameter_mm = 10.0;
  double spot_diameter_mm = 2.5;  // 1/e^2 intensity diameter
  double gap_mm = 0.1;
  double sensitivity_v_per_mm = 5.0;  // slope of X and Y at the centre
  double full_sum_v = 4.0;            // SUM with the whole spot on the detector
  double dark_fraction = 0.02;        // keeps X, Y finite as the light vanishes
  double noise_rms_v = 0.005;
  std::uint32_t seed = 42;
};

class PsdModel {
 public:
  explicit PsdModel(PsdModelOptions options = {});

  // Noise-free outputs; nullopt spot = no light on the detector.
  PsdVoltages ideal(const std::optional<PsdSpot>& spot) const;
  // With the board's noise (advances the seeded generator).
  PsdVoltages measure(const std::optional<PsdSpot>& spot);
  // Starts the reading noise afresh from `seed` (options().seed becomes it): a session's own.
  void reseed(std::uint32_t seed);

  const PsdModelOptions& options() const noexcept { return options_; }

 private:
  PsdModelOptions options_;
  double gain_v_;  // G, chosen so that the slope at the centre is sensitivity_v_per_mm
  std::mt19937 rng_;
  std::normal_distribution<double> noise_;
};

// Which USB-1408FS inputs carry the board's outputs.
struct PsdWiring {
  usb1408fs::Channel x{0, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V};
  usb1408fs::Channel y{1, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V};
  usb1408fs::Channel sum{2, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V};
};

// Feeds a simulated USB-1408FS from the PSD: `spot_at(t)` says where the beam meets the PSD at
// time t seconds. The model is evaluated once per time point and shared by the three channels;
// channels not wired to the PSD read 0 V. `psd` must outlive the returned source.
Usb1408fsModel::AnalogSource psdAnalogSource(
    PsdModel& psd, std::function<std::optional<PsdSpot>(double t)> spot_at, PsdWiring wiring = {});

}  // namespace zerocal::sim
