// The devices of a real cell by kind: the one place that names the vendors. A new controller is
// a folder of its own (its link implementing ControllerConnection), a ControllerKind, and a line
// here; a new PSD readout likewise with PsdReadout and a psd::DaqKind.
#pragma once

#include <memory>

#include "zerocal/cell/cell.h"
#include "zerocal/daemon/config.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/psd/psd.h"

namespace zerocal::service {

// The robot model controller.robot names: a robot file, or the compiled-in IRB 1600-10/1.45.
// Throws ConfigError when the file does not load.
Robot robotOf(const ControllerConfig& config);

// The IRC5 link's options: the controller section's own (controller.irc5), with the robot model
// controller.robot names loaded into them. Throws ConfigError when the robot file does not load.
Irc5Options irc5OptionsOf(const ControllerConfig& config);

// The link to the controller controller.kind names, not connected. Throws ConfigError for
// options the link refuses (a robot file that does not load, say).
std::unique_ptr<ControllerConnection> makeControllerConnection(const ControllerConfig& config);

// The PSD readout daq.kind names, its board opened (daq.serial), reading through `map` on
// `clock`. Throws the board's error when it cannot be opened.
std::unique_ptr<PsdReadout> makePsdReadout(const psd::PsdConfig& config, const psd::PsdMap& map,
                                           CellClock& clock);

}  // namespace zerocal::service
