// The session service's settings, wired in one place (service::daemon_setup, the tests): what
// the planner, the run, the result and the apply coordinator take from the configuration.
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "zerocal/apply/transmission_check.h"
#include "zerocal/cell/controller_link.h"
#include "zerocal/daemon/config.h"
#include "zerocal/record/robot_record.h"
#include "zerocal/session/calibration_run.h"

namespace zerocal::service {

struct ManagerSettings {
  // The configuration's session section: the data folder, what a request leaves out (plan, poses,
  // plan_file, noise_mm: the measurement sigma for plans and solves). Its target_mm is not used
  // here: target_mm below is the default target, set only on a real cell.
  SessionConfig session;
  RunSettings run;
  std::optional<Eigen::Vector3d> target_mm;  // default nominal target; else the backend's
  nlohmann::json config_snapshot;            // written into each session.json
  // What every move costs the controller beyond its motion, when known (the simulated one's
  // model): the result's pose breakdown then shows it per pose, as moves x cost.
  std::optional<MoveOverhead> move_overhead;
  // The controller's time for a move of the robot between two poses (s): a plan's poses are then
  // visited in the order that takes least time (orderForTravel); empty, in the order chosen.
  std::function<double(const Robot& robot, const Joints& from, const Joints& to)> travel_s;
  // Called with a finished session's folder after result.json is written (summary, report),
  // and the robot's history in the record (for the report's trend; empty without a record).
  std::function<void(const std::string& session_dir,
                     const std::vector<record::HistoryEntry>& history)>
      write_reports;
  // How long the recovery of an interrupted apply waits for a controller that refuses or ignores
  // connections: a daemon killed while the controller restarted on new values comes back first.
  std::chrono::milliseconds controller_restart_timeout{90000};
  // How often an interrupted apply that could not be recovered is tried again while the daemon
  // is otherwise idle (a quiet look at the controller; a visible attempt when it holds
  // something new).
  std::chrono::milliseconds recovery_retry{10000};
  // The online apply measures joints 2..5's transmissions before it writes (docs/apply.md).
  apply::TransmissionCheckOptions transmission_check;
  // No technician to move the PSD (zerocald --once and the experiments on the simulated cell,
  // whose PSD moves itself): a session at several placements goes on to the next one at once, at
  // its planned centre, instead of waiting for a continue.
  bool unattended_placements = false;
  // The robot's record (docs/record.md), when the daemon keeps one; not owned, it outlives the
  // manager. A session is recorded when its result is written and again whenever its apply
  // journal changes (an apply, a verification, a rollback, a recovery, an acknowledgement); the
  // control port's `robots` and `history` read it.
  record::RobotRecord* record = nullptr;
};

}  // namespace zerocal::service
