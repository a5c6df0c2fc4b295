// A simulated PSD rig for the demo and the tests: the simulated PSD on a stage, wired to a
// simulated USB-1408FS, read through the real Usb1408fs protocol code over FakeTransport. The
// same bytes cross the seam as with a board on a cable; only time is simulated.
#pragma once

#include <memory>
#include <optional>
#include <ostream>
#include <vector>

#include "zerocal/psd/psd.h"
#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/usb1408fs_model.h"
#include "zerocal/usb1408fs/psd_chain.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::sim {

class SimulatedPsdRig {
 public:
  // `seed` drives the PSD noise; the board's calibration table keeps its own fixed seed, as a
  // real board's EEPROM does not change between runs.
  explicit SimulatedPsdRig(std::uint32_t seed = 42, const usb1408fs::PsdChannels& channels = {});
  SimulatedPsdRig(const SimulatedPsdRig&) = delete;
  SimulatedPsdRig& operator=(const SimulatedPsdRig&) = delete;

  // Where the beam meets the PSD (mm); nullopt: no light on the detector.
  void setSpot(std::optional<PsdSpot> spot) { spot_ = spot; }
  usb1408fs::Usb1408fs& daq() { return *daq_; }
  Usb1408fsModel& board() { return board_; }
  const PsdModel& psd() const { return psd_; }
  const usb1408fs::PsdChannels& channels() const { return channels_; }

 private:
  usb1408fs::PsdChannels channels_;
  Usb1408fsModel board_;
  PsdModel psd_;
  std::optional<PsdSpot> spot_ = PsdSpot{};
  std::unique_ptr<usb1408fs::Usb1408fs> daq_;
};

struct SweepOptions {
  double extent_mm = 0.8;  // the stage covers -extent..+extent on both axes ...
  double step_mm = 0.05;   // ... in this step, row by row
  std::size_t samples = 64;
  double rate_hz = 16000.0;
};

// A stage sweep like the paper's: at every grid position, one averaged reading (readAveraged).
// Throws std::invalid_argument for a step or extent that is not positive, or more than 401
// positions per axis.
std::vector<psd::SweepPoint> simulateSweep(SimulatedPsdRig& rig, const SweepOptions& options);

}  // namespace zerocal::sim
