// The daemon's parts as its configuration describes them, built in one place for zerocald and for
// `zerocal-lab experiment cell` (which repeats the daemon's calibration over seeded simulated
// worlds), so that the experiment measures exactly what the daemon runs.
#pragma once

#include <memory>

#include "zerocal/cell/cell.h"
#include "zerocal/daemon/config.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/session/calibration_run.h"

namespace zerocal::service {

// The run settings of the servo section (stop rule, tolerance, step, iterations, timeout, settle,
// search), the controller's limit margin and the session's measurement sigma. The recovery hooks
// are the session manager's to set (it owns the links).
RunSettings runSettingsOf(const DaemonConfig& config);

// The backend of the backend section: the hardware cell (HardwareBackend), or the simulated cell
// of backend.sim_world or backend.sim_seed (seed 1 when neither): in-process (SimBackend), or with
// the controller in the external zerocal-sim at backend.sim_host:sim_port
// (ExternalSimBackend, which checks at connect that it simulates the same world). The in-process
// cell gives each session its own noise (sim::SessionNoise: the data folder's sessions before it
// count) and applies backend.sim_zero_change_*. Throws ConfigError, and InputError for a zero
// change the configuration's validation would have refused.
std::unique_ptr<CellBackend> makeBackend(const DaemonConfig& config);

// The session manager's settings: data folder, run settings, plan defaults, the nominal target on a
// real cell (the simulated cell's is the one taught on its world), the configuration snapshot
// written into each session, and the summary and report written after each result.
ManagerSettings managerSettingsOf(const DaemonConfig& config);

}  // namespace zerocal::service
