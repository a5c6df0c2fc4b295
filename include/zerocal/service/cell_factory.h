// The devices of a cell as the configuration names them, by kind: the controller link that
// controller.kind's section makes and the PSD readout that daq.kind's makes. Nothing here names a
// vendor: the kinds are listed in one place (zerocal/cell/kinds.h), and each kind's folder makes
// its own devices.
#pragma once

#include <memory>

#include "zerocal/cell/cell.h"
#include "zerocal/cell/controller_kind.h"
#include "zerocal/daemon/config.h"
#include "zerocal/psd/psd.h"

namespace zerocal::service {

// The robot model controller.robot names: a robot file, or the compiled-in IRB 1600-10/1.45.
// Throws ConfigError when the file does not load.
Robot robotOf(const ControllerConfig& config);

// The link to the controller of controller.kind, not connected, driving the robot of
// controller.robot: at the address in the kind's section, or at `endpoint` (the simulated
// cell's controller). Throws ConfigError for options the link refuses (a robot file that does
// not load, say).
std::unique_ptr<ControllerConnection> makeControllerConnection(
    const ControllerConfig& config, const LinkEndpoint* endpoint = nullptr);

// The PSD readout of daq.kind, its board opened, reading through `map` on `clock`. Throws the
// board's error when it cannot be opened.
std::unique_ptr<PsdReadout> makePsdReadout(const DaqConfig& config, const psd::PsdMap& map,
                                           CellClock& clock);

}  // namespace zerocal::service
