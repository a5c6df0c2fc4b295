// A small synchronous client of the control port (docs/protocol.md), for the `zerocal` command
// line, the tests and the load test. Every call has a deadline; nothing blocks forever.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/streambuf.hpp>
#include <chrono>
#include <cstdint>
#include <deque>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "zerocal/error.h"

namespace zerocal::control {

// The connection failed: cannot connect, closed by the daemon, or a deadline passed.
class ConnectionError : public Error {
 public:
  using Error::Error;
};

// The daemon answered {"ok": false}: code and message as sent.
class CommandError : public Error {
 public:
  CommandError(std::string code, const std::string& message)
      : Error(message), code_(std::move(code)) {}
  const std::string& code() const { return code_; }

 private:
  std::string code_;
};

class ControlClient {
 public:
  using Duration = std::chrono::steady_clock::duration;

  ControlClient() = default;
  ~ControlClient();

  // Resolves and connects. Throws ConnectionError.
  void connect(const std::string& host, std::uint16_t port,
               Duration timeout = std::chrono::seconds(5));
  void close();

  // Sends `request` with a fresh numeric "id" and waits for the response with that id; events
  // arriving meanwhile are kept for nextEvent(). Returns the response whatever its "ok". Throws
  // ConnectionError.
  nlohmann::json request(nlohmann::json request, Duration timeout = std::chrono::seconds(10));
  // request(), then throws CommandError when the response is not ok.
  nlohmann::json call(const std::string& cmd, nlohmann::json members = nlohmann::json::object(),
                      Duration timeout = std::chrono::seconds(10));
  // auth with the token; throws CommandError("auth_failed") when refused.
  void authenticate(const std::string& token);

  // The next {"event": ...} line, or nullopt when none comes within `timeout`. Throws
  // ConnectionError when the daemon closed the connection.
  std::optional<nlohmann::json> nextEvent(Duration timeout);

  // Raw access for the protocol tests: bytes as given, one line back (without '\n'), or nullopt
  // on timeout; throws ConnectionError on close.
  void sendRaw(const std::string& bytes, Duration timeout = std::chrono::seconds(5));
  std::optional<std::string> readLine(Duration timeout);

 private:
  // Runs the io_context until the operation finishes or the deadline passes (then the operation
  // is cancelled, and the socket closed unless keep_open). Returns false on timeout.
  bool runFor(Duration timeout, const bool& done, bool keep_open = false);

  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket socket_{io_};
  boost::asio::streambuf input_;
  std::deque<nlohmann::json> events_;
  long long next_id_ = 1;
};

}  // namespace zerocal::control
