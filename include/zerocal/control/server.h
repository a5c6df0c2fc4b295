// The daemon's control port: JSON lines over TCP (docs/protocol.md), served on an io_context the
// daemon owns and runs on one thread. Every connection is handled on that thread; session events
// (from the session's worker thread) and answers of slow commands (`plan` on a helper thread,
// `psd` from the session) are posted back to it. No thread per connection. What a connection
// says is handled by the ProtocolHub (line_connection.h), which the web terminal's WebSocket
// shares.
//
// Lifetime: construct after the io_context and the SessionControl, destroy before either (the
// destructor stops the server and, when it made its own hub, the hub: the event sink is cleared
// and a running preview waited for).
#pragma once

#include <boost/asio/io_context.hpp>
#include <cstdint>
#include <memory>

#include "zerocal/control/server_options.h"
#include "zerocal/service/session_control.h"

namespace zerocal::control {

class ServerCore;  // server.cpp
class ProtocolHub;

class ControlServer {
 public:
  // Installs the event sink on `session`. Throws Error when the options are invalid (no token).
  // `default_request` fills the members a `start` or `plan` request leaves out (SessionManager's
  // defaultRequest(): the configuration's session section).
  ControlServer(boost::asio::io_context& io, service::SessionControl& session,
                ServerOptions options, service::StartRequest default_request = {});
  // The port on a hub another transport shares (ProtocolHub::create); its options are the
  // port's. stop() leaves the hub running: whoever made it stops it.
  explicit ControlServer(std::shared_ptr<ProtocolHub> hub);
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // Binds, listens and starts accepting. Throws Error when the address cannot be bound.
  void start();
  // Closes the listener and every connection of the port; with its own hub, also waits for a
  // running preview and clears the event sink. Idempotent; call on the io thread or when the
  // io_context is not running.
  void stop();
  // The bound port (after start()).
  std::uint16_t port() const;
  // Connections open now; io thread only.
  std::size_t connectionCount() const;

 private:
  std::shared_ptr<ProtocolHub> hub_;
  std::shared_ptr<ServerCore> impl_;
  bool owns_hub_ = false;
};

}  // namespace zerocal::control
