// The simulated cell as the daemon's backend: one SimulatedCell that lives as long as the daemon
// (the robot stays where it was left between sessions, as a real one does), and per session the
// production endpoints attached to it: the real Irc5Client over loopback TCP, the real Usb1408fs
// protocol code over the byte-exact simulated board, and the real PSD chain.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "zerocal/cell/cell.h"
#include "zerocal/cell/controller_kind.h"
#include "zerocal/sim/simulated_cell.h"

namespace zerocal::sim {

// Makes the link to a simulated controller listening at an endpoint: the configured controller
// kind's link (its speeds, margins and timeouts, as for a real controller), pointed at the
// simulator.
using SimLinkFactory = std::function<std::unique_ptr<ControllerConnection>(const LinkEndpoint&)>;

// How the sessions on a SimBackend draw their noise (docs/simulated-cell.md): the backend's k-th
// session (k = 0, 1, ...) starts from sessionNoiseSeed(*first, sessions_before + k), and its
// truth names that seed. Without `first`, the sessions continue the cell's noise streams (the
// seeds of its options) and their truth names none.
struct SessionNoise {
  std::optional<std::uint64_t> first;
  std::uint64_t sessions_before = 0;  // the sessions the data folder held when the daemon started
};

class SimBackend final : public CellBackend {
 public:
  // `link` makes the controller link of each session; without it, an Irc5Client with the
  // simulated cell's own options (SimulatedCell::clientOptions). The simulated controller speaks
  // the IRC5 protocol: a link of another kind is refused here (ConfigError naming
  // controller.kind).
  explicit SimBackend(SimulatedCellOptions options, SimLinkFactory link = {},
                      SessionNoise noise = {});
  const char* name() const override { return "sim"; }
  CellKnowledge knowledge() const override;
  std::unique_ptr<ConnectedCell> connect() override;

  SimulatedCell& cell() { return cell_; }
  // A session begins: its noise starts from its own seed (SessionNoise). Returns that seed, or
  // nullopt when the backend has no SessionNoise::first.
  std::optional<std::uint64_t> beginSession();
  // The seed the current session's noise started from, as beginSession returned it.
  std::optional<std::uint64_t> sessionNoiseSeed() const { return session_seed_; }

 private:
  SimulatedCell cell_;
  SimLinkFactory link_;
  SessionNoise noise_;
  std::uint64_t sessions_begun_ = 0;
  std::optional<std::uint64_t> session_seed_;
};

struct ExternalSimOptions {
  World world;               // the world zerocal-sim must be simulating
  std::string world_source;  // how it was chosen ("backend.sim_seed 3", a file), for messages
  // Where zerocal-sim listens, and the link to it (the controller section's robot, speeds and
  // timeouts); it must be an IRC5 link, as zerocal-sim speaks the IRC5 protocol.
  LinkEndpoint at;
  SimLinkFactory link;
  PsdModelOptions psd;
  std::uint32_t board_seed = 1408;
  double sweep_half_width_mm = 0.8, sweep_step_mm = 0.04;
};

// The simulated cell with the controller in an external zerocal-sim process: the production
// Irc5Client drives it over TCP; the PSD is the in-process simulated USB-1408FS (the same board
// model, transport and PSD chain as SimBackend) lit where zerocal-sim says the beam meets the
// detector, asked over a second connection (request 43, simulator only) so that the servo's link
// carries only its own requests. The clock is the steady clock: zerocal-sim's moves take wall time
// (its --pace). Sessions run on one thread at a time, which also drives the board.
class ExternalSimBackend final : public CellBackend {
 public:
  // Fits the PSD map (a simulated bench sweep); connects nothing.
  explicit ExternalSimBackend(ExternalSimOptions options);
  ~ExternalSimBackend() override;
  ExternalSimBackend(const ExternalSimBackend&) = delete;
  ExternalSimBackend& operator=(const ExternalSimBackend&) = delete;
  const char* name() const override { return "sim"; }
  CellKnowledge knowledge() const override;
  // Its PSD cannot be moved: zerocal-sim's world is fixed (a session at one placement only).
  std::string placementsRefusal() const override;
  // Connects the spot link, checks that zerocal-sim simulates options.world (ConfigError naming
  // both worlds otherwise, before anything moves), then the robot link. Throws as
  // Irc5Client::connect.
  std::unique_ptr<ConnectedCell> connect() override;

 private:
  class Cell;
  ExternalSimOptions options_;
  PsdModel psd_;
  Usb1408fsModel board_;
  psd::PsdMap map_;
  SteadyCellClock clock_;
  Irc5Client* spot_link_ = nullptr;  // the connected cell's, while there is one
  std::string spot_failure_;         // why the spot link failed during the reading in progress
};

}  // namespace zerocal::sim
