// The control server's options, which are also the `control` section of zerocald's configuration
// (zerocal/daemon/config.h; the keys and their units in docs/configuration.md). Kept apart from
// server.h so that the configuration does not pull in Asio.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

namespace zerocal::control {

struct ServerOptions {
  std::string bind_address = "127.0.0.1";
  std::uint16_t port = 7450;  // 0: any free port (tests; port() tells which)
  // The file the daemon reads `token` from (loadToken); the server itself only uses `token`.
  // Required to serve the port; checked when bind_address is not loopback.
  std::string token_file;
  std::string token;  // required, not empty
  // The operator's login (zerocal/control/roles.h): its file (optional; empty: every login is
  // an engineer's) and the token read from it, which must differ from `token`.
  std::string operator_token_file;
  std::string operator_token;
  std::string daemon_version = "unknown";
  // Connections at once. When all are taken, a new connection displaces the oldest one that has
  // not authenticated (so that idle strangers can never lock out an abort); when every one has
  // authenticated, the new one gets a too_many_clients error and is closed.
  std::size_t max_clients = 64;
  // Connections from one peer address at once; beyond it as for max_clients, within that address.
  std::size_t max_clients_per_peer = 16;
  // A connection that has not authenticated this long after it connected is closed.
  std::chrono::milliseconds auth_timeout{std::chrono::seconds(10)};
  // Plan files named in `start` and `plan` requests are file names in this folder (no path
  // components); nothing else is read. Empty: no plan file may be named on the port.
  std::string plan_dir = "/var/lib/zerocal/plans";
  std::size_t max_line_bytes = 65536;  // a longer request line: line_too_long, then closed
  // A connection that completes no request line for this long is closed, unless it subscribed
  // (a watcher is quiet by design; a dead watcher is found by the write limits below).
  std::chrono::milliseconds idle_timeout{std::chrono::minutes(10)};
  // A client that does not read: dropped when this much of its events is queued (configured in
  // KiB, control.max_queued_kib), or when one write has been stuck this long.
  std::size_t max_queued_bytes = 1 << 20;
  std::chrono::milliseconds write_timeout{std::chrono::seconds(30)};
  // Failed `auth` attempts (or commands sent before auth) per connection before it is closed; each
  // failure is answered only after auth_failure_delay, to slow guessing.
  int max_auth_failures = 3;
  std::chrono::milliseconds auth_failure_delay{500};
  // While a session is active, subscribers also get a "status" event this often.
  std::chrono::milliseconds status_period{500};
  // `plan` previews queued or running at once (on one helper thread); more are refused "busy".
  int max_pending_previews = 4;
};

}  // namespace zerocal::control
