#include "zerocal/control/server.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>
#include <set>

#include "zerocal/control/line_connection.h"
#include "zerocal/control/listener.h"
#include "zerocal/control/protocol.h"

namespace zerocal::control {

namespace asio = boost::asio;
using asio::ip::tcp;
using nlohmann::json;

class Connection;

// The TCP port: the listener, and the admission of connections within max_clients and
// max_clients_per_peer. What a connection says is the hub's business.
class ServerCore : public std::enable_shared_from_this<ServerCore> {
 public:
  ServerCore(std::shared_ptr<ProtocolHub> hub)
      : hub_(std::move(hub)),
        options_(hub_->options()),
        listener_(std::make_shared<Listener>(hub_->io(), hub_->logger(), "control")) {}

  void start();
  void stop();
  void remove(Connection* connection);

  std::shared_ptr<ProtocolHub> hub_;
  const ServerOptions& options_;
  std::shared_ptr<Listener> listener_;
  std::set<std::shared_ptr<Connection>> connections_;
  bool stopped_ = false;
  std::uint16_t port_ = 0;

 private:
  void admit(tcp::socket socket);
  void refuse(tcp::socket socket, const std::string& why);
  spdlog::logger& log() { return hub_->log(); }
};

// JSON lines over a TCP socket: a line ends at '\n', read with a streambuf capped at
// max_line_bytes.
class Connection : public LineConnection {
 public:
  Connection(std::shared_ptr<ServerCore> server, tcp::socket socket, std::string peer,
             std::string peer_address)
      : LineConnection(server->hub_, std::move(peer), std::move(peer_address)),
        server_(std::move(server)),
        socket_(std::move(socket)),
        input_(server_->options_.max_line_bytes) {
    boost::system::error_code ec;
    socket_.set_option(tcp::no_delay(true), ec);
    socket_.set_option(asio::socket_base::keep_alive(true), ec);
  }

  static std::shared_ptr<Connection> make(std::shared_ptr<ServerCore> server, tcp::socket socket) {
    boost::system::error_code ec;
    const auto endpoint = socket.remote_endpoint(ec);
    const std::string address = ec ? std::string("?") : endpoint.address().to_string();
    const std::string peer = ec ? address : address + ":" + std::to_string(endpoint.port());
    return std::make_shared<Connection>(std::move(server), std::move(socket), peer, address);
  }

  // Closed to make room for a newer connection: it is told why, and leaves the server's count at
  // once so that the newcomer fits, while its last line is still being written.
  void evict(const json& message) {
    sendAndClose(message);
    server_->remove(this);
  }

  // The socket of a connection that was never started, to refuse it.
  tcp::socket release() {
    abandon();
    return std::move(socket_);
  }

 private:
  std::shared_ptr<Connection> self() {
    return std::static_pointer_cast<Connection>(shared_from_this());
  }

  void readLine() override {
    asio::async_read_until(socket_, input_, '\n',
                           [self = self()](boost::system::error_code ec, std::size_t n) {
                             if (ec == asio::error::not_found) return self->lineTooLong();
                             if (ec) return self->readFailed(ec);
                             std::string line(asio::buffers_begin(self->input_.data()),
                                              asio::buffers_begin(self->input_.data()) + n);
                             self->input_.consume(n);
                             self->received(std::move(line));
                           });
  }

  void writeLine(const Line& line) override {
    asio::async_write(
        socket_, asio::buffer(*line),
        [self = self(), line](boost::system::error_code ec, std::size_t) { self->written(ec); });
  }

  void shutdown() override {
    boost::system::error_code ec;
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
  }

  void left() override { server_->remove(this); }

  std::shared_ptr<ServerCore> server_;
  tcp::socket socket_;
  asio::streambuf input_;
};

void ServerCore::start() {
  port_ = listener_->listen(options_.bind_address, options_.port);
  log().info("control port listening on {}:{}", options_.bind_address, port_);
  listener_->accept([self = shared_from_this()](tcp::socket socket) {
    if (!self->stopped_) self->admit(std::move(socket));
  });
}

void ServerCore::admit(tcp::socket socket) {
  auto connection = Connection::make(shared_from_this(), std::move(socket));
  const std::string& peer = connection->peerAddress();
  // When a limit is reached, the oldest connection within it that has not authenticated makes
  // room: an authenticated client (an abort) always gets in unless every slot is authenticated.
  const auto makeRoom = [this](bool same_peer_only, const std::string& address) {
    std::shared_ptr<Connection> oldest;
    for (const auto& c : connections_)
      if (!c->authenticated() && (!same_peer_only || c->peerAddress() == address) &&
          (!oldest || c->connectedAt() < oldest->connectedAt()))
        oldest = c;
    if (!oldest) return false;
    const std::string limit = same_peer_only ? fmt::format("{} connections from {}",
                                                           options_.max_clients_per_peer, address)
                                             : fmt::format("{} connections", options_.max_clients);
    log().warn("{}: closed to make room, it had not authenticated ({} are open)", oldest->peer(),
               limit);
    oldest->evict(errorResponse(nullptr, code::kTooManyClients,
                                fmt::format("closed to make room for a new connection: {} are "
                                            "open and this one has not authenticated; closing",
                                            limit)));
    return true;
  };
  std::size_t from_peer = 0;
  for (const auto& c : connections_) from_peer += c->peerAddress() == peer;
  if (from_peer >= options_.max_clients_per_peer && !makeRoom(true, peer))
    return refuse(connection->release(), std::to_string(from_peer) +
                                             " authenticated connections from " + peer +
                                             " are open already");
  if (connections_.size() >= options_.max_clients && !makeRoom(false, peer))
    return refuse(connection->release(), "the daemon serves " +
                                             std::to_string(options_.max_clients) +
                                             " authenticated clients already");
  connections_.insert(connection);
  connection->start();
}

void ServerCore::refuse(tcp::socket socket, const std::string& why) {
  auto s = std::make_shared<tcp::socket>(std::move(socket));
  boost::system::error_code ec;
  const auto peer = s->remote_endpoint(ec);
  log().warn("{}: refused, {}", ec ? std::string("?") : peer.address().to_string(), why);
  auto line = makeLine(errorResponse(nullptr, code::kTooManyClients, why + "; try later"));
  // The socket's own buffer takes a line this short; if not, the peer loses the explanation only.
  s->non_blocking(true, ec);
  asio::write(*s, asio::buffer(*line), ec);
  s->shutdown(tcp::socket::shutdown_both, ec);
  s->close(ec);
}

void ServerCore::stop() {
  if (stopped_) return;
  stopped_ = true;
  listener_->close();
  auto open = connections_;  // close() removes from the set
  for (const auto& c : open) c->close();
  connections_.clear();
}

void ServerCore::remove(Connection* connection) {
  for (auto it = connections_.begin(); it != connections_.end(); ++it)
    if (it->get() == connection) {
      connections_.erase(it);
      return;
    }
}

ControlServer::ControlServer(asio::io_context& io, service::SessionControl& session,
                             ServerOptions options, service::StartRequest default_request)
    : ControlServer(
          ProtocolHub::create(io, session, std::move(options), std::move(default_request))) {
  owns_hub_ = true;
}

ControlServer::ControlServer(std::shared_ptr<ProtocolHub> hub)
    : hub_(hub), impl_(std::make_shared<ServerCore>(std::move(hub))) {}

ControlServer::~ControlServer() { stop(); }

void ControlServer::start() { impl_->start(); }
void ControlServer::stop() {
  impl_->stop();
  if (owns_hub_) hub_->stop();
}
std::uint16_t ControlServer::port() const { return impl_->port_; }
std::size_t ControlServer::connectionCount() const { return impl_->connections_.size(); }

}  // namespace zerocal::control
