// The daemon's side of systemd's service protocol (sd_notify(3)): readiness, a status line,
// stopping, and the watchdog. Under systemd with Type=notify, NOTIFY_SOCKET names the socket; when
// it is not set (a terminal, a test, --once) every call here does nothing.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <functional>
#include <optional>
#include <string>

namespace zerocal {

// READY=1 with a STATUS= line: systemd starts the units that wait for zerocald now.
void notifyReady(const std::string& status);
void notifyStatus(const std::string& status);
// STOPPING=1: the daemon is shutting down (aborting a session, stopping the robot).
void notifyStopping(const std::string& status);

// The interval within which systemd wants WATCHDOG=1 (the unit's WatchdogSec=), when the
// watchdog is enabled for this process; nullopt otherwise.
std::optional<std::chrono::microseconds> watchdogInterval();

// Feeds systemd's watchdog from the thread that runs `io` (the daemon's I/O thread), every half
// interval, as long as `stuck` says the other threads make progress. `stuck` returns why a thread
// is stuck, or nullopt; while it does, the watchdog goes hungry and systemd restarts the daemon
// (the reason is logged once). A blocked I/O thread starves it too.
class Watchdog {
 public:
  using StuckCheck = std::function<std::optional<std::string>()>;
  Watchdog(boost::asio::io_context& io, std::chrono::microseconds interval, StuckCheck stuck);
  // Both on the io_context's thread (or while it does not run).
  void start();
  void stop();

 private:
  void arm();
  boost::asio::steady_timer timer_;
  std::chrono::microseconds interval_;
  StuckCheck stuck_;
  bool reported_ = false;  // the current stall is in the log already
  bool stopped_ = false;
};

}  // namespace zerocal
