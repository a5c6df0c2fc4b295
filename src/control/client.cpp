#include "zerocal/control/client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/write.hpp>

#include "zerocal/control/messages.h"

namespace zerocal::control {

namespace asio = boost::asio;
using asio::ip::tcp;
using nlohmann::json;

ControlClient::~ControlClient() { close(); }

void ControlClient::close() {
  boost::system::error_code ec;
  socket_.shutdown(tcp::socket::shutdown_both, ec);
  socket_.close(ec);
}

bool ControlClient::runFor(Duration timeout, const bool& done, bool keep_open) {
  io_.restart();
  io_.run_for(timeout);
  if (done) return true;
  // Deadline passed: cancel, then let the handler run with operation_aborted. A read that timed
  // out leaves the connection usable (bytes already read stay in input_); anything else does not.
  boost::system::error_code ec;
  if (keep_open)
    socket_.cancel(ec);
  else
    close();
  io_.restart();
  io_.run();
  return false;
}

void ControlClient::connect(const std::string& host, std::uint16_t port, Duration timeout) {
  tcp::resolver resolver(io_);
  boost::system::error_code ec;
  const auto endpoints = resolver.resolve(host, std::to_string(port), ec);
  if (ec) throw ConnectionError("cannot resolve " + host + ": " + ec.message());
  bool done = false;
  asio::async_connect(socket_, endpoints, [&](boost::system::error_code e, const tcp::endpoint&) {
    ec = e;
    done = true;
  });
  const std::string where = host + ":" + std::to_string(port);
  if (!runFor(timeout, done)) throw ConnectionError("cannot connect to " + where + ": timed out");
  if (ec) throw ConnectionError("cannot connect to " + where + ": " + ec.message());
  socket_.set_option(tcp::no_delay(true), ec);
}

void ControlClient::sendRaw(const std::string& bytes, Duration timeout) {
  boost::system::error_code ec;
  bool done = false;
  asio::async_write(socket_, asio::buffer(bytes), [&](boost::system::error_code e, std::size_t) {
    ec = e;
    done = true;
  });
  if (!runFor(timeout, done)) throw ConnectionError("sending to the daemon timed out");
  if (ec) throw ConnectionError("the daemon closed the connection: " + ec.message());
}

std::optional<std::string> ControlClient::readLine(Duration timeout) {
  boost::system::error_code ec;
  std::size_t n = 0;
  bool done = false;
  asio::async_read_until(socket_, input_, '\n', [&](boost::system::error_code e, std::size_t k) {
    ec = e;
    n = k;
    done = true;
  });
  if (!runFor(timeout, done, true)) return std::nullopt;
  if (ec) throw ConnectionError("the daemon closed the connection");
  std::string line(asio::buffers_begin(input_.data()), asio::buffers_begin(input_.data()) + n);
  input_.consume(n);
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  return line;
}

json ControlClient::request(json message, Duration timeout) {
  const auto id = next_id_++;
  message["id"] = id;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  sendRaw(toLine(message), timeout);
  for (;;) {
    const auto left = deadline - std::chrono::steady_clock::now();
    auto line = left > Duration::zero() ? readLine(left) : std::nullopt;
    if (!line)
      throw ConnectionError("no answer to '" + message.value("cmd", std::string()) +
                            "' from the daemon in time");
    json reply = json::parse(*line, nullptr, false);
    if (reply.is_discarded() || !reply.is_object()) throw ConnectionError("garbled answer");
    if (reply.contains("event")) {
      events_.push_back(std::move(reply));
      continue;
    }
    // An unsolicited error (no id: too many clients, a line too long) is the answer too.
    if (reply.value("id", json()) == json(id) || reply["id"].is_null()) return reply;
  }
}

json ControlClient::call(const std::string& cmd, json members, Duration timeout) {
  members["cmd"] = cmd;
  json reply = request(std::move(members), timeout);
  if (!reply.value("ok", false)) {
    const auto& e = reply.value("error", json::object());
    throw CommandError(e.value("code", std::string("unknown")),
                       e.value("message", std::string("refused")));
  }
  return reply;
}

void ControlClient::authenticate(const std::string& token) { call("auth", {{"token", token}}); }

std::optional<json> ControlClient::nextEvent(Duration timeout) {
  if (!events_.empty()) {
    json e = std::move(events_.front());
    events_.pop_front();
    return e;
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= Duration::zero()) return std::nullopt;
    auto line = readLine(left);
    if (!line) return std::nullopt;
    json message = json::parse(*line, nullptr, false);
    if (message.is_object() && message.contains("event")) return message;
  }
}

}  // namespace zerocal::control
