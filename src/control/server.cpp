#include "zerocal/control/server.h"

#include <fmt/format.h>

#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/asio/write.hpp>
#include <deque>
#include <functional>
#include <set>

#include "zerocal/calib/format.h"
#include "zerocal/control/protocol.h"
#include "zerocal/control/token.h"
#include "zerocal/daemon/logging.h"

namespace zerocal::control {

namespace asio = boost::asio;
using asio::ip::tcp;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using Line = std::shared_ptr<const std::string>;

namespace {

Line makeLine(const json& message) { return std::make_shared<const std::string>(toLine(message)); }

json okResponse(const json& id) { return {{"id", id}, {"ok", true}}; }

// Commands a connection may send before it has authenticated; none of them touches the session.
bool isOpenCommand(const std::string& cmd) {
  return cmd == "hello" || cmd == "version" || cmd == "auth";
}

// A plan file named in the request must be a plain file name in plan_dir: the port never reads
// any other path (the token file, /proc, a FIFO). The configuration's own plan_file is kept.
service::StartRequest planFileInPlanDir(service::StartRequest start, const json& request,
                                        const std::string& plan_dir) {
  const auto named = request.find("plan_file");
  if (named == request.end() || named->is_null()) return start;
  const std::string name = start.plan_file;
  if (plan_dir.empty())
    throw BadRequest(
        "plan_file: this daemon takes no plan files over the port "
        "(control.plan_dir is not set)");
  const bool plain = !name.empty() && name.size() <= 255 &&
                     name.find_first_of("/\\") == std::string::npos && name != "." &&
                     name != ".." && name[0] != '.';
  if (!plain)
    throw BadRequest(
        "plan_file: a file name in the daemon's plan folder (control.plan_dir), "
        "without a path");
  start.plan_file = plan_dir + "/" + name;
  return start;
}

const std::vector<std::string> kCommands{
    "hello",    "version",  "auth",        "status",      "start",  "abort", "resume",
    "sessions", "result",   "subscribe",   "unsubscribe", "psd",    "plan",  "apply",
    "verify",   "continue", "acknowledge", "robots",      "history"};

}  // namespace

class Connection;

class ServerCore : public std::enable_shared_from_this<ServerCore> {
 public:
  ServerCore(asio::io_context& io, service::SessionControl& session, ServerOptions options,
             service::StartRequest default_request)
      : io_(io),
        session_(session),
        options_(std::move(options)),
        default_request_(std::move(default_request)),
        acceptor_(io),
        accept_retry_(io),
        status_timer_(io),
        log_(makeLogger("control")) {}

  void start();
  void stop();
  void remove(Connection* connection);
  void broadcast(const json& event);
  void startStatusTimer();

  asio::io_context& io_;
  service::SessionControl& session_;
  const ServerOptions options_;
  const service::StartRequest default_request_;
  tcp::acceptor acceptor_;
  asio::steady_timer accept_retry_;
  asio::steady_timer status_timer_;
  std::shared_ptr<spdlog::logger> log_;
  std::set<std::shared_ptr<Connection>> connections_;
  asio::thread_pool previews_{1};
  std::atomic<int> pending_previews_{0};
  bool stopped_ = false;
  std::uint16_t port_ = 0;

 private:
  void accept();
  void admit(tcp::socket socket);
  void refuse(tcp::socket socket, const std::string& why);
};

class Connection : public std::enable_shared_from_this<Connection> {
 public:
  Connection(std::shared_ptr<ServerCore> server, tcp::socket socket)
      : server_(std::move(server)),
        socket_(std::move(socket)),
        input_(server_->options_.max_line_bytes),
        watchdog_(server_->io_),
        delay_(server_->io_) {
    boost::system::error_code ec;
    const auto peer = socket_.remote_endpoint(ec);
    peer_address_ = ec ? std::string("?") : peer.address().to_string();
    peer_ = ec ? peer_address_ : peer_address_ + ":" + std::to_string(peer.port());
    connected_at_ = Clock::now();
    socket_.set_option(tcp::no_delay(true), ec);
    socket_.set_option(asio::socket_base::keep_alive(true), ec);
  }

  void start() {
    last_line_ = Clock::now();
    armWatchdog();
    read();
  }

  // An event line, and an answer (or a last word before closing). Each kind is counted apart
  // against max_queued_bytes: a client that does not read its events, or sends requests without
  // reading the answers, is dropped. One answer is always queued, whatever its size (a page of the
  // session list may be larger than the limit), and never counts against the events'.
  void sendEvent(const Line& line) { enqueue(line, false); }
  void send(const json& message) { enqueue(makeLine(message), true); }

  // Answers, then closes once everything queued is written.
  void sendAndClose(const json& message) {
    send(message);
    closing_ = true;
    if (!writing_ && !closed_) close();
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    boost::system::error_code ec;
    watchdog_.cancel();
    delay_.cancel();
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
    server_->remove(this);
  }

  // Closed to make room for a newer connection: it is told why, and leaves the server's count at
  // once so that the newcomer fits, while its last line is still being written.
  void evict(const json& message) {
    sendAndClose(message);
    server_->remove(this);
  }

  // The socket of a connection that was never started, to refuse it.
  tcp::socket release() {
    closed_ = true;
    watchdog_.cancel();
    delay_.cancel();
    return std::move(socket_);
  }

  bool subscribed() const { return subscribed_; }
  bool authenticated() const { return authenticated_; }
  const std::string& peer() const { return peer_; }
  // The peer's address without the port: what the per-peer limit counts.
  const std::string& peerAddress() const { return peer_address_; }
  Clock::time_point connectedAt() const { return connected_at_; }

 private:
  void read() {
    if (closed_ || closing_) return;
    asio::async_read_until(socket_, input_, '\n',
                           [self = shared_from_this()](boost::system::error_code ec,
                                                       std::size_t n) { self->onRead(ec, n); });
  }

  void onRead(boost::system::error_code ec, std::size_t n) {
    if (closed_) return;
    if (ec == asio::error::not_found) {
      server_->log_->warn("{}: request line over {} bytes; closing", peer_,
                          server_->options_.max_line_bytes);
      sendAndClose(errorResponse(nullptr, code::kLineTooLong,
                                 "a request line is limited to " +
                                     std::to_string(server_->options_.max_line_bytes) +
                                     " bytes; closing"));
      return;
    }
    if (ec) {  // eof, reset, or closed by us
      if (ec != asio::error::eof && ec != asio::error::operation_aborted)
        server_->log_->debug("{}: read: {}", peer_, ec.message());
      close();
      return;
    }
    std::string line(asio::buffers_begin(input_.data()), asio::buffers_begin(input_.data()) + n);
    input_.consume(n);
    last_line_ = Clock::now();
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    if (line.empty()) return read();
    // One request at a time per connection: the next line is read once this one is answered,
    // which bounds what one client can have in flight.
    try {
      if (handle(line)) read();
    } catch (const std::exception& e) {
      server_->log_->error("{}: unexpected failure: {}", peer_, e.what());
      send(errorResponse(nullptr, code::kInternal, e.what()));
      read();
    }
  }

  // Returns true when answered; false when the answer comes later (then it calls finish()).
  bool handle(const std::string& line) {
    json request;
    try {
      request = parseRequestLine(line);
    } catch (const RequestTooDeep& e) {
      send(errorResponse(nullptr, code::kBadJson, std::string("not a request: ") + e.what()));
      return true;
    } catch (const json::exception& e) {
      send(errorResponse(nullptr, code::kBadJson, std::string("not a JSON object: ") + e.what()));
      return true;
    }
    if (!request.is_object()) {
      send(errorResponse(nullptr, code::kBadRequest, "a request is a JSON object"));
      return true;
    }
    const json id = request.contains("id") ? request["id"] : json(nullptr);
    const auto cmd_it = request.find("cmd");
    if (cmd_it == request.end() || !cmd_it->is_string()) {
      send(errorResponse(id, code::kBadRequest, "cmd: expected a string"));
      return true;
    }
    const std::string cmd = cmd_it->get<std::string>();
    if (!isOpenCommand(cmd) && !authenticated_) {
      return authFailure(id, code::kUnauthenticated,
                         "'" + cmd + "' needs authentication: send {\"cmd\":\"auth\",...} first");
    }
    try {
      return dispatch(id, cmd, request);
    } catch (const BadRequest& e) {
      send(errorResponse(id, code::kBadRequest, e.what()));
    } catch (const service::Refused& e) {
      send(errorResponse(id, e.code(), e.what()));
    } catch (const json::exception& e) {
      send(errorResponse(id, code::kBadRequest, e.what()));
    } catch (const std::exception& e) {
      // A result.json that does not parse, a session folder that cannot be written: the request
      // fails, the connection and the daemon go on.
      server_->log_->error("{}: {} failed: {}", peer_, cmd, e.what());
      send(errorResponse(id, code::kInternal, e.what()));
    }
    return true;
  }

  bool dispatch(const json& id, const std::string& cmd, const json& request) {
    auto& session = server_->session_;
    const auto& options = server_->options_;
    json r = okResponse(id);
    if (cmd == "hello" || cmd == "version") {
      r["protocol"] = kProtocolVersion;
      r["daemon"] = options.daemon_version;
      if (cmd == "hello") {
        r["authenticated"] = authenticated_;
        r["commands"] = kCommands;
      }
    } else if (cmd == "auth") {
      const auto token = request.find("token");
      if (token == request.end() || !token->is_string() ||
          !tokensEqual(token->get<std::string>(), options.token))
        return authFailure(id, code::kAuthFailed, "wrong token");
      // debug: a terminal polling `zerocal status` authenticates on every connection.
      if (!authenticated_) server_->log_->debug("{}: authenticated", peer_);
      authenticated_ = true;
      auth_failures_ = 0;
    } else if (cmd == "status") {
      r["status"] = toJson(session.status());
    } else if (cmd == "start") {
      const auto start = planFileInPlanDir(parseStartRequest(request, server_->default_request_),
                                           request, options.plan_dir);
      return answerAside(id, [&session, start, log = server_->log_, peer = peer_] {
        const auto session_id = session.start(start);
        log->info("{}: started session {}", peer, session_id);
        return json{{"session", session_id}};
      });
    } else if (cmd == "resume") {
      const service::ResumeRequest resume = parseResumeRequest(request);
      const auto session_id = session.resume(resume);
      if (resume.skip_pose > 0)
        server_->log_->warn("{}: resumed session {}, skipping pose {}", peer_, session_id,
                            resume.skip_pose);
      else
        server_->log_->info("{}: resumed session {}", peer_, session_id);
      r["session"] = session_id;
    } else if (cmd == "continue") {
      const auto session_id = session.continueSession(parseContinueRequest(request));
      server_->log_->info("{}: continued session {} at its next PSD placement", peer_, session_id);
      r["session"] = session_id;
    } else if (cmd == "apply") {
      const service::ApplyRequest apply = parseApplyRequest(request);
      const auto session_id = session.apply(apply);
      server_->log_->warn("{}: applying session {} to the controller", peer_, session_id);
      r["session"] = session_id;
    } else if (cmd == "verify") {
      const auto session_id = session.verify(parseVerifyRequest(request));
      server_->log_->info("{}: verifying session {}", peer_, session_id);
      r["session"] = session_id;
    } else if (cmd == "acknowledge") {
      const auto session_id = session.acknowledge(parseAcknowledgeRequest(request));
      server_->log_->warn("{}: acknowledged the interrupted apply of session {}", peer_,
                          session_id);
      r["session"] = session_id;
    } else if (cmd == "abort") {
      const bool aborted = session.abort();
      if (aborted) server_->log_->warn("{}: aborted the session", peer_);
      r["aborted"] = aborted;
    } else if (cmd == "sessions") {
      r.update(sessionsPage(session.sessions(), parseSessionsRequest(request)));
    } else if (cmd == "robots") {
      r["robots"] = toJson(session.robots());
    } else if (cmd == "history") {
      // A query of the record (about a millisecond for a robot's hundred sessions): answered
      // here, as `sessions` is.
      const record::RobotId robot = parseHistoryRequest(request, session.robots());
      json history = json::array();
      for (const record::HistoryEntry& e : session.history(robot)) history.push_back(toJson(e));
      r["robot"] = {{"robot_type", robot.robot_type}, {"serial", robot.serial}};
      r["history"] = std::move(history);
    } else if (cmd == "result") {
      const ResultFile result = session.result(optionalString(request, "session"));
      r["result"] = toJson(result);
      // What became of the offsets: a result the controller holds reads otherwise than one it
      // does not.
      if (const auto applied = session.lastApply(result.session)) r["apply"] = toJson(*applied);
    } else if (cmd == "subscribe") {
      subscribed_ = true;
      server_->startStatusTimer();
      r["status"] = toJson(session.status());  // the state the events that follow start from
    } else if (cmd == "unsubscribe") {
      subscribed_ = false;
    } else if (cmd == "psd") {
      readPsd(id);
      return false;
    } else if (cmd == "plan") {
      const auto plan = planFileInPlanDir(parseStartRequest(request, server_->default_request_),
                                          request, options.plan_dir);
      return answerAside(id, [&session, plan] {
        return json{{"plan", toJson(session.preview(plan))}};
      });
    } else {
      send(errorResponse(id, code::kUnknownCommand, "unknown command '" + cmd + "'"));
      return true;
    }
    send(r);
    return true;
  }

  bool authFailure(const json& id, const char* error_code, const std::string& message) {
    ++auth_failures_;
    const bool last = auth_failures_ >= server_->options_.max_auth_failures;
    server_->log_->warn("{}: authentication failed ({}, {} of {}){}", peer_, error_code,
                        auth_failures_, server_->options_.max_auth_failures,
                        last ? "; closing" : "");
    auto response = errorResponse(id, error_code, last ? message + "; closing" : message);
    // The answer waits, so that guessing costs time; the connection reads nothing meanwhile.
    delay_.expires_after(server_->options_.auth_failure_delay);
    delay_.async_wait([self = shared_from_this(), response, last](boost::system::error_code ec) {
      if (ec || self->closed_) return;
      if (last) return self->sendAndClose(response);
      self->send(response);
      self->read();
    });
    return false;
  }

  void readPsd(const json& id) {
    auto executor = server_->io_.get_executor();
    std::weak_ptr<Connection> weak = shared_from_this();
    server_->session_.readPsd([executor, weak, id](std::optional<service::LiveReading> reading,
                                                   const std::string& error) {
      asio::post(executor, [weak, id, reading = std::move(reading), error] {
        auto self = weak.lock();
        if (!self || self->closed_) return;
        if (reading) {
          json r = okResponse(id);
          r["reading"] = toJson(*reading);
          self->send(r);
        } else {
          self->send(errorResponse(id, code::kUnavailable, error));
        }
        self->read();
      });
    });
  }

  // Work that plans (a preview, a start) takes about a second: it runs on the planning thread so
  // that every other connection goes on being answered, and this one reads its next line once
  // the answer is sent. `work` returns the members of the ok response or throws.
  bool answerAside(const json& id, std::function<json()> work) {
    auto& server = *server_;
    if (server.pending_previews_.fetch_add(1) >= server.options_.max_pending_previews) {
      server.pending_previews_.fetch_sub(1);
      send(errorResponse(id, "busy", "too many plans queued; try again shortly"));
      return true;
    }
    auto executor = server.io_.get_executor();
    std::weak_ptr<Connection> weak = shared_from_this();
    auto* pending = &server.pending_previews_;  // the pool is joined before the core dies
    asio::post(server.previews_, [executor, weak, id, work = std::move(work), pending] {
      json response;
      try {
        response = okResponse(id);
        response.update(work());
      } catch (const service::Refused& e) {
        response = errorResponse(id, e.code(), e.what());
      } catch (const BadRequest& e) {
        response = errorResponse(id, code::kBadRequest, e.what());
      } catch (const InputError& e) {  // a plan file that is not there or does not parse
        response = errorResponse(id, code::kBadRequest, e.what());
      } catch (const std::exception& e) {
        response = errorResponse(id, code::kInternal, e.what());
      }
      pending->fetch_sub(1);
      asio::post(executor, [weak, response = std::move(response)] {
        auto self = weak.lock();
        if (!self || self->closed_) return;
        self->send(response);
        self->read();
      });
    });
    return false;
  }

  void enqueue(const Line& line, bool answer) {
    if (closed_) return;
    std::size_t& queued = answer ? queued_answer_bytes_ : queued_event_bytes_;
    if ((!answer || queued > 0) && queued + line->size() > server_->options_.max_queued_bytes) {
      server_->log_->warn("{}: dropped, it does not read ({} bytes of {} queued)", peer_, queued,
                          answer ? "answers" : "events");
      close();
      return;
    }
    queued += line->size();
    queue_.push_back({line, answer});
    if (!writing_) write();
  }

  void write() {
    writing_ = true;
    write_started_ = Clock::now();
    asio::async_write(socket_, asio::buffer(*queue_.front().line),
                      [self = shared_from_this()](boost::system::error_code ec, std::size_t) {
                        self->onWrite(ec);
                      });
  }

  void onWrite(boost::system::error_code ec) {
    writing_ = false;
    if (closed_) return;
    (queue_.front().answer ? queued_answer_bytes_ : queued_event_bytes_) -=
        queue_.front().line->size();
    queue_.pop_front();
    if (ec) return close();
    if (!queue_.empty()) return write();
    if (closing_) close();
  }

  void armWatchdog() {
    const auto& o = server_->options_;
    const auto tick = std::min({std::chrono::milliseconds(1000), o.idle_timeout / 4,
                                o.write_timeout / 4, o.auth_timeout / 4});
    watchdog_.expires_after(std::max(tick, std::chrono::milliseconds(1)));
    watchdog_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
      if (ec || self->closed_) return;
      self->checkTimeouts();
    });
  }

  void checkTimeouts() {
    const auto& o = server_->options_;
    const auto now = Clock::now();
    if (!authenticated_ && !closing_ && now - connected_at_ > o.auth_timeout) {
      server_->log_->info("{}: not authenticated within {} ms; closing", peer_,
                          o.auth_timeout.count());
      sendAndClose(errorResponse(nullptr, code::kUnauthenticated,
                                 "authenticate within " + std::to_string(o.auth_timeout.count()) +
                                     " ms of connecting; closing"));
      if (closed_) return;
    }
    if (writing_ && now - write_started_ > o.write_timeout) {
      server_->log_->warn("{}: dropped, a write was stuck for over {} ms", peer_,
                          o.write_timeout.count());
      return close();
    }
    // Idle: no complete line for idle_timeout. A half-open peer, or one trickling a line byte by
    // byte, never completes one. Subscribers and connections waiting for an answer are exempt.
    if (!subscribed_ && !closing_ && now - last_line_ > o.idle_timeout) {
      server_->log_->info("{}: idle for {} ms; closing", peer_, o.idle_timeout.count());
      sendAndClose({{"event", "closing"}, {"reason", "idle timeout"}});
      if (closed_) return;
    }
    armWatchdog();
  }

  std::shared_ptr<ServerCore> server_;
  tcp::socket socket_;
  asio::streambuf input_;
  asio::steady_timer watchdog_;
  asio::steady_timer delay_;
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
  bool authenticated_ = false;
  bool subscribed_ = false;
  int auth_failures_ = 0;
  Clock::time_point last_line_;
  Clock::time_point write_started_;
};

void ServerCore::start() {
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(options_.bind_address, ec);
  if (ec) throw Error("control.bind_address '" + options_.bind_address + "' is not an IP address");
  const tcp::endpoint endpoint(address, options_.port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    throw Error("cannot listen on " + options_.bind_address + ":" + std::to_string(options_.port) +
                ": " + ec.message());
  port_ = acceptor_.local_endpoint().port();
  log_->info("control port listening on {}:{}", options_.bind_address, port_);
  accept();
}

void ServerCore::accept() {
  acceptor_.async_accept(
      [self = shared_from_this()](boost::system::error_code ec, tcp::socket socket) {
        if (self->stopped_) return;
        if (ec) {
          // Out of descriptors, typically: wait a little rather than spin, then go on accepting.
          self->log_->warn("accept: {}", ec.message());
          self->accept_retry_.expires_after(std::chrono::milliseconds(100));
          self->accept_retry_.async_wait([self](boost::system::error_code e) {
            if (!e && !self->stopped_) self->accept();
          });
          return;
        }
        self->admit(std::move(socket));
        self->accept();
      });
}

void ServerCore::admit(tcp::socket socket) {
  auto connection = std::make_shared<Connection>(shared_from_this(), std::move(socket));
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
    log_->warn("{}: closed to make room, it had not authenticated ({} are open)", oldest->peer(),
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
  log_->warn("{}: refused, {}", ec ? std::string("?") : peer.address().to_string(), why);
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
  boost::system::error_code ec;
  acceptor_.close(ec);
  accept_retry_.cancel();
  status_timer_.cancel();
  auto open = connections_;  // close() removes from the set
  for (const auto& c : open) c->close();
  connections_.clear();
  previews_.stop();
  previews_.join();
}

void ServerCore::remove(Connection* connection) {
  for (auto it = connections_.begin(); it != connections_.end(); ++it)
    if (it->get() == connection) {
      connections_.erase(it);
      return;
    }
}

void ServerCore::broadcast(const json& event) {
  if (stopped_) return;
  const auto line = makeLine(event);  // one copy shared by every subscriber
  auto open = connections_;           // sendEvent() may drop a connection
  for (const auto& c : open)
    if (c->subscribed()) c->sendEvent(line);
}

void ServerCore::startStatusTimer() {
  if (stopped_ || options_.status_period.count() <= 0) return;
  // Already armed: expiry() is in the future.
  if (status_timer_.expiry() > Clock::now()) return;
  status_timer_.expires_after(options_.status_period);
  status_timer_.async_wait([weak = weak_from_this()](boost::system::error_code ec) {
    auto self = weak.lock();
    if (ec || !self || self->stopped_) return;
    bool any = false;
    for (const auto& c : self->connections_) any = any || c->subscribed();
    if (!any) return;  // re-armed by the next subscribe
    const auto status = self->session_.status();
    if (service::isActive(status.state))
      self->broadcast({{"event", "status"}, {"status", toJson(status)}});
    self->startStatusTimer();
  });
}

ControlServer::ControlServer(asio::io_context& io, service::SessionControl& session,
                             ServerOptions options, service::StartRequest default_request) {
  if (options.token.empty()) throw Error("the control port needs a token (control.token_file)");
  if (options.max_clients < 1 || options.max_line_bytes < 64 || options.max_auth_failures < 1 ||
      options.max_clients_per_peer < 1 || options.auth_timeout.count() < 1)
    throw Error("control options out of range");
  impl_ = std::make_shared<ServerCore>(io, session, std::move(options), std::move(default_request));
  auto executor = io.get_executor();
  std::weak_ptr<ServerCore> weak = impl_;
  // Called on the session's worker thread: only a post, never a wait; the line is made on the
  // I/O thread.
  session.setEventSink([executor, weak](const service::SessionEvent& event) {
    asio::post(executor, [weak, event] {
      if (auto self = weak.lock()) self->broadcast(toJson(event));
    });
  });
}

ControlServer::~ControlServer() {
  impl_->session_.setEventSink(nullptr);
  stop();
}

void ControlServer::start() { impl_->start(); }
void ControlServer::stop() { impl_->stop(); }
std::uint16_t ControlServer::port() const { return impl_->port_; }
std::size_t ControlServer::connectionCount() const { return impl_->connections_.size(); }

}  // namespace zerocal::control
