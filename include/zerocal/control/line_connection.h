// The control protocol (docs/protocol.md) independent of what carries its lines: the TCP port
// (server.h) and the web terminal's WebSocket (zerocal/web/web_server.h) both hand each request
// line to a LineConnection and write what it queues, so that there is one implementation of the
// commands, the authentication and the limits, and one event sink fanning out to both.
//
// Everything here runs on the io thread of the io_context the hub was made with; session events
// (from the session's worker) and the answers of slow commands (`plan`, `start` on the hub's
// planning thread, `psd` from the session) are posted to it.
#pragma once

#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "zerocal/control/roles.h"
#include "zerocal/control/server_options.h"
#include "zerocal/service/session_control.h"

namespace spdlog {
class logger;
}

namespace zerocal::control {

// One protocol line, '\n' included; an event's line is shared by every subscriber.
using Line = std::shared_ptr<const std::string>;
Line makeLine(const nlohmann::json& message);

class LineConnection;

// What every connection of every transport shares: the session, the protocol's options (the
// control section: token, limits, plan folder), the planning thread and the subscribers.
class ProtocolHub : public std::enable_shared_from_this<ProtocolHub> {
 public:
  // Installs the event sink on `session`. Throws Error when the options have no token or a limit
  // is out of range. `default_request` fills what a `start` or `plan` request leaves out.
  static std::shared_ptr<ProtocolHub> create(boost::asio::io_context& io,
                                             service::SessionControl& session,
                                             ServerOptions options,
                                             service::StartRequest default_request = {});
  ~ProtocolHub();
  ProtocolHub(const ProtocolHub&) = delete;
  ProtocolHub& operator=(const ProtocolHub&) = delete;

  // Clears the event sink, closes every connection of every transport and waits for a running
  // plan. Idempotent; io thread, or when the io_context is not running. Call it before the
  // session is destroyed (the destructor calls it too).
  void stop();
  bool stopped() const { return stopped_; }
  const ServerOptions& options() const { return options_; }
  boost::asio::io_context& io() { return io_; }
  spdlog::logger& log() { return *log_; }
  const std::shared_ptr<spdlog::logger>& logger() const { return log_; }
  // Connections open now, of every transport; io thread only.
  std::size_t connectionCount() const { return connections_.size(); }

 private:
  friend class LineConnection;
  ProtocolHub(boost::asio::io_context& io, service::SessionControl& session, ServerOptions options,
              service::StartRequest default_request);
  void broadcast(const nlohmann::json& event);
  void startStatusTimer();

  boost::asio::io_context& io_;
  service::SessionControl& session_;
  const ServerOptions options_;
  const service::StartRequest default_request_;
  boost::asio::steady_timer status_timer_;
  std::shared_ptr<spdlog::logger> log_;
  std::set<std::shared_ptr<LineConnection>> connections_;
  boost::asio::thread_pool previews_{1};
  std::atomic<int> pending_previews_{0};
  bool stopped_ = false;
};

// The protocol's side of one connection: it parses and answers request lines, one at a time,
// queues answers and events within the limits, and enforces the timeouts. A transport derives
// from it and does the I/O: one read of a line, one write of a line at a time.
class LineConnection : public std::enable_shared_from_this<LineConnection> {
 public:
  using Clock = std::chrono::steady_clock;

  // `peer` names the connection in the log ("127.0.0.1:51544"); `peer_address` is what the
  // per-peer limit counts.
  LineConnection(std::shared_ptr<ProtocolHub> hub, std::string peer, std::string peer_address);
  virtual ~LineConnection() = default;
  LineConnection(const LineConnection&) = delete;
  LineConnection& operator=(const LineConnection&) = delete;

  // Joins the hub's connections, arms the timeouts and reads the first line.
  void start();
  // An event line, and an answer (or a last word before closing). Each kind is counted apart
  // against max_queued_bytes: a client that does not read its events, or sends requests without
  // reading the answers, is dropped. One answer is always queued, whatever its size (a page of the
  // session list may be larger than the limit), and never counts against the events'.
  void sendEvent(const Line& line) { enqueue(line, false); }
  void send(const nlohmann::json& message) { enqueue(makeLine(message), true); }
  // Answers, then closes once everything queued is written.
  void sendAndClose(const nlohmann::json& message);
  void close();

  bool subscribed() const { return subscribed_; }
  bool authenticated() const { return role_ != Role::kNone; }
  Role role() const { return role_; }
  bool isClosed() const { return closed_; }
  const std::string& peer() const { return peer_; }
  const std::string& peerAddress() const { return peer_address_; }
  Clock::time_point connectedAt() const { return connected_at_; }

 protected:
  // The transport's part. readLine: one asynchronous read, ending in received(), lineTooLong()
  // or readFailed(). writeLine: one asynchronous write of `line` (its '\n' is the TCP framing;
  // a message-framed transport may leave it out), ending in written(). shutdown: close the
  // socket, which cancels its operations. left: the connection closed, leave the transport's
  // own list (called once).
  virtual void readLine() = 0;
  virtual void writeLine(const Line& line) = 0;
  virtual void shutdown() = 0;
  virtual void left() {}
  // Checked with the timeouts: a reason to close the connection now (a web login that expired),
  // or "" to go on.
  virtual std::string revoked() const { return {}; }

  void received(std::string line);
  void lineTooLong();
  void readFailed(boost::system::error_code ec);
  void written(boost::system::error_code ec);
  // The transport authenticated the connection itself (a WebSocket opened with a valid login
  // cookie, of `role`): as if it had sent a right `auth`.
  void authenticateByTransport(Role role) { role_ = role; }
  // Marks a connection that was never started as closed, to hand its socket back.
  void abandon();
  ProtocolHub& hub() { return *hub_; }

 private:
  void read();
  bool handle(const std::string& line);
  bool dispatch(const nlohmann::json& id, const std::string& cmd, const nlohmann::json& request);
  bool authFailure(const nlohmann::json& id, const char* error_code, const std::string& message);
  void readPsd(const nlohmann::json& id);
  bool answerAside(const nlohmann::json& id, std::function<nlohmann::json()> work);
  void enqueue(const Line& line, bool answer);
  void writeNext();
  void armWatchdog();
  void checkTimeouts();

  std::shared_ptr<ProtocolHub> hub_;
  boost::asio::steady_timer watchdog_;
  boost::asio::steady_timer delay_;
  std::string peer_;
  std::string peer_address_;
  Clock::time_point connected_at_;
  struct Queued {
    Line line;
    bool answer;  // else an event
  };
  std::deque<Queued> queue_;
  std::size_t queued_event_bytes_ = 0;
  std::size_t queued_answer_bytes_ = 0;
  bool writing_ = false;
  bool closing_ = false;
  bool closed_ = false;
  Role role_ = Role::kNone;
  bool subscribed_ = false;
  int auth_failures_ = 0;
  Clock::time_point last_line_;
  Clock::time_point write_started_;
};

}  // namespace zerocal::control
