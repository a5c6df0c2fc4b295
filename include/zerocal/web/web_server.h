// The shop-floor terminal in a browser (docs/web.md): HTTP and a WebSocket (Boost.Beast) on the
// daemon's io_context, beside the TCP control port, over TLS when a certificate and key are
// given. The HTTP side serves the page files from web.root and, to a logged-in browser, each
// session's report.html and summary.txt under /sessions/ID/; it exchanges the token, POSTed
// once, for a login cookie (HttpOnly, SameSite=Strict, expiring; Secure with TLS). The WebSocket
// at /ws carries the control protocol's lines, one per text message, through the same
// ProtocolHub as the TCP port: the same commands, events, refusals and limits.
//
// Lifetime: construct after the io_context and the hub, destroy before either.
#pragma once

#include <boost/asio/io_context.hpp>
#include <cstdint>
#include <memory>
#include <string>

#include "zerocal/web/web_options.h"

namespace zerocal::control {
class ProtocolHub;
}

namespace zerocal::web {

class WebCore;  // web_server.cpp

// The page files beside the running program: <its folder>/../share/zerocal/web.
std::string defaultWebRoot();

class WebServer {
 public:
  // Throws Error when the page folder (options.root, or defaultWebRoot() when empty) holds no
  // index.html, the address is not loopback without TLS and the network is not said to be
  // trusted, or only one of the certificate and key is given, or either cannot be read.
  WebServer(boost::asio::io_context& io, std::shared_ptr<control::ProtocolHub> hub,
            WebOptions options);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds, listens and starts accepting. Throws Error when the address cannot be bound.
  void start();
  // Closes the listener, every HTTP connection and every WebSocket. Idempotent; io thread, or
  // when the io_context is not running.
  void stop();
  std::uint16_t port() const;  // after start()
  const std::string& root() const;
  // HTTP connections and WebSockets open now; io thread only.
  std::size_t connectionCount() const;

 private:
  std::shared_ptr<WebCore> impl_;
};

}  // namespace zerocal::web
