// The session worker's connection to the cell: kept between sessions (connecting takes time and
// a controller restarted meanwhile shows at the first request), dropped after a fault so that the
// next user connects afresh. Worker thread only, like the cell itself.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "zerocal/cell/cell.h"
#include "zerocal/service/session_worker.h"

namespace zerocal::service {

// Who the controller says the robot is, and the motor calibration the session measures against.
struct CellIdentity {
  RobotInfo robot;  // empty members when the controller did not say
  // The controller's cal_offset values (rad); absent when its link offers none or it failed.
  std::optional<std::array<double, 6>> cal_offset_rad;
};

class CellConnection {
 public:
  // Both outlive the connection; `worker`'s progress mark is set while connecting.
  CellConnection(CellBackend& backend, SessionWorker& worker);
  // Stops the robot and closes the links.
  ~CellConnection();

  bool connected() const { return cell_ != nullptr; }
  // The connected cell, connecting it first when it is not. Throws what the backend throws.
  ConnectedCell& connect();
  // Connects, waiting up to `timeout` while the controller does not serve (a transient LinkError:
  // one restarting) unless `abort` is set. Throws the last error after that.
  void connectWaitingForRestart(std::chrono::milliseconds timeout, const std::atomic<bool>& abort);
  // Closes the links (after a fault: they may be in any state).
  void drop() noexcept { cell_.reset(); }
  // Stops the robot, when connected.
  void stopRobot() noexcept;
  // The connected cell; connected() must hold.
  ConnectedCell& cell() { return *cell_; }
  const std::string& backendName() const { return backend_name_; }

  // What a session does first once connected: which robot this is, as its controller says (the
  // result names it), and the controller's motor calibration (an apply checks it is still
  // there). A link dropped since the last session (a controller restarted by an apply or a power
  // cycle) is made again here, before anything moves. Never throws: what the controller does not
  // say is logged as a warning on session `session_id` and left empty.
  CellIdentity identify(const std::string& session_id);

 private:
  CellBackend& backend_;
  SessionWorker& worker_;
  std::string backend_name_;
  std::unique_ptr<ConnectedCell> cell_;
};

}  // namespace zerocal::service
