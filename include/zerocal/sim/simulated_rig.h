// The simulated cell with the production endpoints attached, as a session uses them: the real
// Irc5Client connected over loopback TCP, the real Usb1408fs protocol code over FakeTransport, and
// the real PSD chain reading it. Throws as its parts on setup.
#pragma once

#include <functional>
#include <utility>

#include "zerocal/calib/cell_model.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/sim/simulated_cell.h"
#include "zerocal/usb1408fs/psd_readout.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::sim {

struct SimulatedRig {
  // `adjust` may change the client's options (speeds, margins) before it connects.
  explicit SimulatedRig(SimulatedCellOptions options,
                        const std::function<void(Irc5Options&)>& adjust = {})
      : cell(std::move(options)),
        client([&] {
          Irc5Options o = cell.clientOptions();
          if (adjust) adjust(o);
          return o;
        }()),
        daq(cell.boardOpener()),
        psd(daq, cell.psdMap(), cell, simulatedReadout().board, simulatedReadout().psd) {
    client.connect();
  }

  SimulatedCell cell;
  Irc5Client client;
  usb1408fs::Usb1408fs daq;
  usb1408fs::ChainPsdReader psd;
};

// What a session on the simulated cell is given, as a technician would give it on a real one:
// the nominal robot and laser, the PSD's mounting orientation as configured, and the PSD centre
// as taught by jogging (World::psd_rotation_configured and psd_centre_taught_mm: a few degrees
// and a few mm off the truth in the realistic world).
struct SessionKnowledge {
  CellModel cell;
  Eigen::Vector3d taught_centre;
};

inline SessionKnowledge knowledgeOf(const World& world) {
  SessionKnowledge k;
  k.cell.robot = world.robot;
  k.cell.psd_rotation = world.psd_rotation_configured;
  k.taught_centre = world.psd_centre_taught_mm;
  return k;
}

}  // namespace zerocal::sim
