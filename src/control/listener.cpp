#include "zerocal/control/listener.h"

#include <spdlog/spdlog.h>

#include "zerocal/error.h"

namespace zerocal::control {

namespace asio = boost::asio;
using asio::ip::tcp;

Listener::Listener(asio::io_context& io, std::shared_ptr<spdlog::logger> log, std::string section)
    : acceptor_(io), retry_(io), log_(std::move(log)), section_(std::move(section)) {}

std::uint16_t Listener::listen(const std::string& bind_address, std::uint16_t port) {
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(bind_address, ec);
  if (ec) throw Error(section_ + ".bind_address '" + bind_address + "' is not an IP address");
  const tcp::endpoint endpoint(address, port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    throw Error("cannot listen on " + bind_address + ":" + std::to_string(port) + ": " +
                ec.message());
  return acceptor_.local_endpoint().port();
}

void Listener::accept(Admit admit) {
  admit_ = std::move(admit);
  acceptNext();
}

void Listener::acceptNext() {
  acceptor_.async_accept(
      [self = shared_from_this()](boost::system::error_code ec, tcp::socket socket) {
        if (self->closed_) return;
        if (ec) {
          // Out of descriptors, typically: wait a little rather than spin, then go on accepting.
          self->log_->warn("{}: accept: {}", self->section_, ec.message());
          self->retry_.expires_after(std::chrono::milliseconds(100));
          self->retry_.async_wait([self](boost::system::error_code e) {
            if (!e && !self->closed_) self->acceptNext();
          });
          return;
        }
        self->admit_(std::move(socket));
        if (!self->closed_) self->acceptNext();
      });
}

void Listener::close() {
  if (closed_) return;
  closed_ = true;
  boost::system::error_code ec;
  acceptor_.close(ec);
  retry_.cancel();
  admit_ = nullptr;
}

}  // namespace zerocal::control
