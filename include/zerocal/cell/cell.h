// The cell a calibration session runs on, whatever its devices: a robot controller behind
// ControllerLink, a PSD behind PsdReader, and the cell's clock. The daemon's main picks a
// CellBackend from the configuration (the simulated cell, or the IRC5 link plus the USB-1408FS)
// and hands it to the SessionManager, which knows nothing else about where the robot is.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/cell/controller_link.h"
#include "zerocal/cell/psd_reader.h"

namespace zerocal {

// What is known about the cell before anything is connected: the nominal robot and laser, the
// PSD's mounting orientation, and its centre as taught (a few mm off is fine).
struct CellKnowledge {
  CellModel cell;
  Eigen::Vector3d taught_centre_mm = Eigen::Vector3d::Zero();
  // Which map turns the PSD's volts into millimetres, for the result: its source (a file, a
  // simulated sweep) and fingerprint (psd::PsdMap::fingerprint).
  std::string psd_map;
};

// A connected cell, owned by one session at a time. Destroying it closes the links.
class ConnectedCell {
 public:
  virtual ~ConnectedCell() = default;
  virtual ControllerLink& robot() = 0;
  virtual PsdReader& psd() = 0;
  virtual CellClock& clock() = 0;
  // The controller's motor calibration (for an online apply); nullptr when its link offers none.
  virtual ControllerCalibration* calibration() { return nullptr; }
  // Closes and reopens the controller connection (bounded attempts); throws the last LinkError.
  virtual void reconnectRobot() = 0;
  // Closes and reopens the acquisition board (after an unplug); throws the DAQ's error.
  virtual void reopenPsd() = 0;
  // Stops the robot (between moves: the controller finishes a move in progress). Never throws.
  virtual void stopRobot() noexcept = 0;
  // A session begins on this cell: called once per session, after the controller's identity is
  // read and before its first move. The simulated cell starts the session's own noise here
  // (docs/simulated-cell.md); a real cell has nothing to do.
  virtual void beginSession() {}
  // The seed the session's noise was drawn from, on a simulated cell only (its truth).
  virtual std::optional<std::uint64_t> truthNoiseSeed() const { return std::nullopt; }
  // The true offsets delta2..delta5 in degrees, on a simulated cell only (for its reports).
  virtual std::optional<std::array<double, 4>> truthDeg() const { return std::nullopt; }
  // The whole simulated world as a world file (docs/simulated-cell.md), on a simulated cell only:
  // written beside the session's result as its truth.
  virtual std::optional<std::string> truthWorldYaml() const { return std::nullopt; }
  // The PSD stands at `placement` (1-based) of a session whose placements are planned at
  // `planned_centres_mm` (base frame, mm; placement 1's first). On a real cell the technician
  // has put it there and this does nothing; the simulated cell moves its detector (placement 1:
  // where its world has it). Throws Error when the cell cannot.
  virtual void placePsd(int placement, const std::vector<Eigen::Vector3d>& planned_centres_mm) {
    (void)placement;
    (void)planned_centres_mm;
  }
};

class CellBackend {
 public:
  virtual ~CellBackend() = default;
  virtual const char* name() const = 0;  // "sim" or "hardware", for logs and status
  virtual CellKnowledge knowledge() const = 0;
  // Why sessions at several PSD placements cannot run on this cell, in a sentence; empty when
  // they can (a technician moves the PSD, or the simulated cell does).
  virtual std::string placementsRefusal() const { return {}; }
  // Connects the controller and the board. Throws zerocal::Error (LinkError, the DAQ's errors)
  // with a message a technician can act on.
  virtual std::unique_ptr<ConnectedCell> connect() = 0;
};

}  // namespace zerocal
