// A listening TCP socket that hands every accepted connection on, for the control port and the
// web terminal alike. An accept that fails (out of descriptors, typically) is retried after a
// pause rather than in a spin. io thread only.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace spdlog {
class logger;
}

namespace zerocal::control {

class Listener : public std::enable_shared_from_this<Listener> {
 public:
  using Admit = std::function<void(boost::asio::ip::tcp::socket)>;

  // `section` names the configuration section in messages ("control", "web").
  Listener(boost::asio::io_context& io, std::shared_ptr<spdlog::logger> log, std::string section);

  // Binds and listens. Throws Error: "SECTION.bind_address 'X' is not an IP address", or "cannot
  // listen on ADDRESS:PORT: why" (in use, not an address of this machine). Returns the bound port.
  std::uint16_t listen(const std::string& address, std::uint16_t port);
  // Accepts until close(), each connection to `admit`.
  void accept(Admit admit);
  // Closes the socket and forgets `admit` (which may hold its owner). Idempotent.
  void close();

 private:
  void acceptNext();

  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::steady_timer retry_;
  std::shared_ptr<spdlog::logger> log_;
  std::string section_;
  Admit admit_;
  bool closed_ = false;
};

}  // namespace zerocal::control
