// The simulated cell in one object: one World shared by the simulated IRC5 (a real TCP server on
// loopback, port 0) and the simulated USB-1408FS whose analog inputs come from the PSD model at
// the world's current beam hit. Clients connect to it with the real Irc5Client and the real
// Usb1408fs protocol code (through FakeTransport), exactly as to a real cell.
//
// Time: nowS() is the controller's simulated time (warm_s at start, then its moves) plus the
// board's (scans) plus the waits asked through waitS() (settling, back-off); nothing sleeps. The
// board must be driven from one thread (the one that owns the Usb1408fs).
#pragma once

#include <cstdint>
#include <memory>

#include "zerocal/irc5/irc5_client.h"
#include "zerocal/psd/psd.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/sim_controller.h"
#include "zerocal/sim/usb1408fs_model.h"
#include "zerocal/sim/world.h"
#include "zerocal/usb1408fs/psd_chain.h"
#include "zerocal/usb1408fs/psd_readout.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::sim {

struct SimulatedCellOptions {
  World world;
  std::uint64_t controller_seed = 1;  // repeatability noise of the moves
  double pace = 0.0;  // wall seconds per simulated second of a move (SimControllerOptions::pace)
  // The controller's time at start (s): a robot that has been working that long, its arm warm
  // (SimControllerOptions::warm_s, backend.sim_warm_s); 0 a cold arm.
  double warm_s = 0.0;
  irc5::MotionCosts motion;  // what each move costs the controller (SimControllerOptions::motion)
  // The PSD's light signal wired to the controller (the continuous spot search, SimSearchSignal).
  bool search_signal = true;
  PsdModelOptions psd;              // detector, board noise and its seed
  std::uint32_t board_seed = 1408;  // the board's calibration table
  Joints start_joints{0, 0, 0, 0, 30, 0};
  // Whether an apply may have a revolution counter updated remotely (the simulator playing the
  // technician at once), or, as on an IRC5 over RAPID, only a technician at the FlexPendant can
  // (SimController::updateRevolutionCounter, called by whoever plays the technician): the
  // daemon's apply then waits for one (docs/apply.md).
  bool remote_counter_update = true;
  // The stage sweep the PSD map is fitted from (as in the paper: a probe stage over the centre).
  double sweep_half_width_mm = 0.8, sweep_step_mm = 0.04;
};

// The simulated cell of one seed: the world randomWorld(seed, kind), and the controller's and the
// PSD's noise drawn from the same seed (the first session's; SimBackend's SessionNoise gives each
// later session its own) (backend.sim_seed of the daemon, the seeded cells of the
// tests). kIdeal is for tests that need exact figures; a session's default is kRealistic.
SimulatedCellOptions seededCellOptions(std::uint64_t seed, WorldKind kind = WorldKind::kRealistic);

// The PSD map fitted from a simulated stage sweep of the detector `psd` describes (with the next
// seed: the bench's noise, not the session's).
psd::PsdMap simulatedPsdMap(PsdModelOptions psd, double half_width_mm, double step_mm);

class SimulatedCell final : public CellClock {
 public:
  // Starts the controller on its own I/O thread. Throws as SimController.
  explicit SimulatedCell(SimulatedCellOptions options);
  ~SimulatedCell() override;
  SimulatedCell(const SimulatedCell&) = delete;
  SimulatedCell& operator=(const SimulatedCell&) = delete;

  SimController& controller() { return *controller_; }
  Usb1408fsModel& board() { return board_; }
  usb1408fs::Usb1408fs::Opener boardOpener() { return FakeTransport::opener(board_); }
  // The map fitted from a simulated sweep of this cell's detector.
  const psd::PsdMap& psdMap() const { return map_; }
  // Options for an Irc5Client pointed at this cell's controller.
  Irc5Options clientOptions() const;
  const World& world() const { return controller_->world(); }
  const SimulatedCellOptions& options() const { return options_; }

  // Starts a session's own noise from `seed`: the controller's per-session draws
  // (SimController::reseedNoise) and the PSD's reading noise (from seed + 100, paired as
  // seededCellOptions pairs them, so that reseeding with a seed's own number changes nothing).
  // The PSD map stays the bench's. From the thread that drives the cell, between moves.
  void reseedNoise(std::uint64_t seed);
  // The seed the controller's per-session draws last started from.
  std::uint64_t noiseSeed() const { return controller_->noiseSeed(); }

  double nowS() noexcept override;
  // Advances the cell's clock; nothing sleeps.
  void waitS(double seconds) noexcept override;

 private:
  SimulatedCellOptions options_;
  std::unique_ptr<SimController> controller_;
  PsdModel psd_;
  Usb1408fsModel board_;
  psd::PsdMap map_;
  double waited_s_ = 0;  // waitS() so far; one thread (the session's) drives the cell
};

// How the simulated cell reads its board: 64 scans at 16 kHz, a reading in 4 ms of cell time,
// and the default light threshold. The daemon's daq section is for the real board; the simulated
// sessions, their figures and tests are made with this readout.
struct SimulatedReadout {
  usb1408fs::BoardSettings board;
  psd::PsdConfig psd;
};
SimulatedReadout simulatedReadout();

}  // namespace zerocal::sim
