// The web terminal's options, which are also the `web` section of zerocald's configuration
// (zerocal/daemon/config.h; the keys in docs/configuration.md, the terminal in docs/web.md). Kept
// apart from web_server.h so that the configuration does not pull in Beast.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace zerocal::web {

inline constexpr std::uint16_t kDefaultWebPort = 7451;

struct WebOptions {
  // Serve the terminal at all. Unset (`auto`): zerocald serves it with the simulated backend
  // only (webEnabled() in zerocal/daemon/config.h); a real cell opts in.
  std::optional<bool> enabled;
  std::string bind_address = "127.0.0.1";
  std::uint16_t port = kDefaultWebPort;  // 0: any free port (tests; port() tells which)
  // Without TLS an address other than loopback is refused unless the configuration says that
  // the network between the browsers and the cell PC is trusted.
  bool trusted_network = false;
  // TLS: the certificate (PEM, its chain after it) and its private key (PEM, unencrypted). Both
  // set: the terminal is served over HTTPS and WSS only, on any address; neither: plain HTTP.
  std::string tls_certificate;
  std::string tls_key;
  // The page files (index.html, ...). Empty: <the program's folder>/../share/zerocal/web, where
  // both the build tree (build/share/zerocal/web) and the package (/usr/share/zerocal/web) have
  // them (defaultWebRoot()).
  std::string root;
  // A login (the cookie the token was exchanged for) is good this long, then the browser asks for
  // the token again; open WebSockets of that login are closed when it expires.
  std::chrono::milliseconds session_lifetime{std::chrono::hours(8)};
  // The daemon's session folders (session.data_dir; zerocald sets it, it is no key of the web
  // section): a logged-in browser reads each session's report.html and summary.txt under
  // /sessions/ID/. Empty: no reports are served.
  std::string sessions_dir;

  // Not configuration keys: limits of the HTTP side (Beast's parser limits and deadlines).
  std::size_t max_header_bytes = 8 * 1024;  // a request's header, request line included
  std::size_t max_body_bytes = 4 * 1024;    // a request's body (the login's JSON is ~100 bytes)
  std::chrono::milliseconds request_timeout{std::chrono::seconds(10)};  // to send one request
  std::size_t max_connections = 128;  // HTTP connections and WebSockets at once
  std::size_t max_logins = 256;       // logins held at once; the oldest is forgotten
};

}  // namespace zerocal::web
