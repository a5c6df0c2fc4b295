// The daemon's control port: JSON lines over TCP (docs/protocol.md), served on an io_context the
// daemon owns and runs on one thread. Every connection is handled on that thread; session events
// (from the session's worker thread) and answers of slow commands (`plan` on a helper thread,
// `psd` from the session) are posted back to it. No thread per connection.
//
// Lifetime: construct after the io_context and the SessionControl, destroy before either (the
// destructor stops the server, clears the event sink and waits for a running preview).
#pragma once

#include <boost/asio/io_context.hpp>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "zerocal/daemon/config.h"
#include "zerocal/service/session_control.h"

namespace zerocal::control {

class ServerCore;  // server.cpp

struct ServerOptions {
  std::string bind_address = "127.0.0.1";
  std::uint16_t port = 7450;  // 0: any free port (tests; port() tells which)
  std::string token;          // required, not empty (loadToken)
  std::string daemon_version = "unknown";
  // What `start` and `plan` use for the members a request leaves out (SessionManager's
  // defaultRequest(): the configuration's session section).
  service::StartRequest default_request;
  // Connections at once. When all are taken, a new connection displaces the oldest one that has
  // not authenticated (so that idle strangers can never lock out an abort); when every one has
  // authenticated, the new one gets a too_many_clients error and is closed.
  std::size_t max_clients = 64;
  // Connections from one peer address at once; more are refused (too_many_clients).
  std::size_t max_clients_per_peer = 16;
  // A connection that has not authenticated this long after it connected is closed.
  std::chrono::milliseconds auth_timeout{std::chrono::seconds(10)};
  // Plan files named in `start` and `plan` requests are file names in this folder (no path
  // components); nothing else is read. Empty: no plan file may be named on the port.
  std::string plan_dir;
  std::size_t max_line_bytes = 65536;  // a longer request line: line_too_long, then closed
  // A connection that completes no request line for this long is closed, unless it subscribed
  // (a watcher is quiet by design; a dead watcher is found by the write limits below).
  std::chrono::milliseconds idle_timeout{std::chrono::minutes(10)};
  // A client that does not read: dropped when this much output is queued for it, or when one
  // write has been stuck this long.
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

// The options the control section describes; the token comes from loadToken(token_file).
ServerOptions serverOptions(const ControlConfig& config, std::string token,
                            std::string daemon_version);

class ControlServer {
 public:
  // Installs the event sink on `session`. Throws Error when the options are invalid (no token).
  ControlServer(boost::asio::io_context& io, service::SessionControl& session,
                ServerOptions options);
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // Binds, listens and starts accepting. Throws Error when the address cannot be bound.
  void start();
  // Closes the listener and every connection, waits for a running preview, clears the event
  // sink. Idempotent; call on the io thread or when the io_context is not running.
  void stop();
  // The bound port (after start()).
  std::uint16_t port() const;
  // Connections open now; io thread only.
  std::size_t connectionCount() const;

 private:
  std::shared_ptr<ServerCore> impl_;
};

}  // namespace zerocal::control
