#include "zerocal/control/line_connection.h"

#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>

#include "zerocal/control/protocol.h"
#include "zerocal/control/token.h"
#include "zerocal/daemon/logging.h"

namespace zerocal::control {

namespace asio = boost::asio;
using nlohmann::json;
using Clock = LineConnection::Clock;

Line makeLine(const json& message) { return std::make_shared<const std::string>(toLine(message)); }

namespace {

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

// -- the hub ------------------------------------------------------------------------------------

std::shared_ptr<ProtocolHub> ProtocolHub::create(asio::io_context& io,
                                                 service::SessionControl& session,
                                                 ServerOptions options,
                                                 service::StartRequest default_request) {
  if (options.token.empty()) throw Error("the control port needs a token (control.token_file)");
  if (options.max_clients < 1 || options.max_line_bytes < 64 || options.max_auth_failures < 1 ||
      options.max_clients_per_peer < 1 || options.auth_timeout.count() < 1)
    throw Error("control options out of range");
  std::shared_ptr<ProtocolHub> hub(
      new ProtocolHub(io, session, std::move(options), std::move(default_request)));
  auto executor = io.get_executor();
  std::weak_ptr<ProtocolHub> weak = hub;
  // Called on the session's worker thread: only a post, never a wait; the line is made on the
  // I/O thread, once, for the subscribers of every transport.
  session.setEventSink([executor, weak](const service::SessionEvent& event) {
    asio::post(executor, [weak, event] {
      if (auto self = weak.lock()) self->broadcast(toJson(event));
    });
  });
  return hub;
}

ProtocolHub::ProtocolHub(asio::io_context& io, service::SessionControl& session,
                         ServerOptions options, service::StartRequest default_request)
    : io_(io),
      session_(session),
      options_(std::move(options)),
      default_request_(std::move(default_request)),
      status_timer_(io),
      log_(makeLogger("control")) {}

// Not the session: a hub stopped already may outlive it (in a handler the io_context destroys).
ProtocolHub::~ProtocolHub() { stop(); }

void ProtocolHub::stop() {
  if (stopped_) return;
  stopped_ = true;
  session_.setEventSink(nullptr);
  status_timer_.cancel();
  auto open = connections_;  // close() removes from the set
  for (const auto& c : open) c->close();
  connections_.clear();
  previews_.stop();
  previews_.join();
}

void ProtocolHub::broadcast(const json& event) {
  if (stopped_) return;
  const auto line = makeLine(event);  // one copy shared by every subscriber
  auto open = connections_;           // sendEvent() may drop a connection
  for (const auto& c : open)
    if (c->subscribed()) c->sendEvent(line);
}

void ProtocolHub::startStatusTimer() {
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

// -- one connection -----------------------------------------------------------------------------

LineConnection::LineConnection(std::shared_ptr<ProtocolHub> hub, std::string peer,
                               std::string peer_address)
    : hub_(std::move(hub)),
      watchdog_(hub_->io_),
      delay_(hub_->io_),
      peer_(std::move(peer)),
      peer_address_(std::move(peer_address)),
      connected_at_(Clock::now()) {}

void LineConnection::start() {
  if (hub_->stopped_) return abandon();
  hub_->connections_.insert(shared_from_this());
  last_line_ = Clock::now();
  armWatchdog();
  read();
}

void LineConnection::sendAndClose(const json& message) {
  send(message);
  closing_ = true;
  if (!writing_ && !closed_) close();
}

void LineConnection::close() {
  if (closed_) return;
  closed_ = true;
  watchdog_.cancel();
  delay_.cancel();
  shutdown();
  auto self = shared_from_this();  // the hub's set may hold the last reference
  hub_->connections_.erase(self);
  left();
}

void LineConnection::abandon() {
  closed_ = true;
  watchdog_.cancel();
  delay_.cancel();
}

void LineConnection::read() {
  if (closed_ || closing_) return;
  readLine();
}

void LineConnection::lineTooLong() {
  if (closed_) return;
  hub_->log_->warn("{}: request line over {} bytes; closing", peer_, hub_->options_.max_line_bytes);
  sendAndClose(errorResponse(nullptr, code::kLineTooLong,
                             "a request line is limited to " +
                                 std::to_string(hub_->options_.max_line_bytes) +
                                 " bytes; closing"));
}

void LineConnection::readFailed(boost::system::error_code ec) {
  if (closed_) return;
  // eof, reset, or closed by us
  if (ec != asio::error::eof && ec != asio::error::operation_aborted)
    hub_->log_->debug("{}: read: {}", peer_, ec.message());
  close();
}

void LineConnection::received(std::string line) {
  if (closed_) return;
  last_line_ = Clock::now();
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  if (line.empty()) return read();
  // One request at a time per connection: the next line is read once this one is answered,
  // which bounds what one client can have in flight.
  try {
    if (handle(line)) read();
  } catch (const std::exception& e) {
    hub_->log_->error("{}: unexpected failure: {}", peer_, e.what());
    send(errorResponse(nullptr, code::kInternal, e.what()));
    read();
  }
}

void LineConnection::writeNext() {
  writing_ = true;
  write_started_ = Clock::now();
  writeLine(queue_.front().line);
}

void LineConnection::written(boost::system::error_code ec) {
  writing_ = false;
  if (closed_) return;
  (queue_.front().answer ? queued_answer_bytes_ : queued_event_bytes_) -=
      queue_.front().line->size();
  queue_.pop_front();
  if (ec) return close();
  if (!queue_.empty()) return writeNext();
  if (closing_) close();
}

// Returns true when answered; false when the answer comes later (then it calls finish()).
bool LineConnection::handle(const std::string& line) {
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
  if (!isOpenCommand(cmd) && !authenticated()) {
    return authFailure(id, code::kUnauthenticated,
                       "'" + cmd + "' needs authentication: send {\"cmd\":\"auth\",...} first");
  }
  // A start is judged by its kind once the request is read (dispatch).
  if (const std::string why = forbiddenCommand(role_, cmd); !why.empty()) {
    send(errorResponse(id, code::kForbidden, why));
    return true;
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
    hub_->log_->error("{}: {} failed: {}", peer_, cmd, e.what());
    send(errorResponse(id, code::kInternal, e.what()));
  }
  return true;
}

bool LineConnection::dispatch(const json& id, const std::string& cmd, const json& request) {
  auto& session = hub_->session_;
  const auto& options = hub_->options_;
  json r = okResponse(id);
  if (cmd == "hello" || cmd == "version") {
    r["protocol"] = kProtocolVersion;
    r["daemon"] = options.daemon_version;
    if (cmd == "hello") {
      r["authenticated"] = authenticated();
      r["role"] = roleName(role_);
      r["commands"] = kCommands;
    }
  } else if (cmd == "auth") {
    const auto token = request.find("token");
    const Role role = token != request.end() && token->is_string()
                          ? roleOfToken(options, token->get<std::string>())
                          : Role::kNone;
    if (role == Role::kNone) return authFailure(id, code::kAuthFailed, "wrong token");
    // debug: a terminal polling `zerocal status` authenticates on every connection.
    if (role_ != role) hub_->log_->debug("{}: authenticated as the {}", peer_, roleName(role));
    role_ = role;
    auth_failures_ = 0;
    r["role"] = roleName(role);
  } else if (cmd == "status") {
    r["status"] = toJson(session.status());
  } else if (cmd == "start") {
    const auto start = planFileInPlanDir(parseStartRequest(request, hub_->default_request_),
                                         request, options.plan_dir);
    if (const std::string why = forbiddenStart(role_, start.kind); !why.empty()) {
      send(errorResponse(id, code::kForbidden, why));
      return true;
    }
    return answerAside(id, [&session, start, log = hub_->log_, peer = peer_] {
      const auto session_id = session.start(start);
      log->info("{}: started session {}", peer, session_id);
      return json{{"session", session_id}};
    });
  } else if (cmd == "resume") {
    const service::ResumeRequest resume = parseResumeRequest(request);
    const auto session_id = session.resume(resume);
    if (resume.skip_pose > 0)
      hub_->log_->warn("{}: resumed session {}, skipping pose {}", peer_, session_id,
                       resume.skip_pose);
    else
      hub_->log_->info("{}: resumed session {}", peer_, session_id);
    r["session"] = session_id;
  } else if (cmd == "continue") {
    const auto session_id = session.continueSession(parseContinueRequest(request));
    hub_->log_->info("{}: continued session {} at its next PSD placement", peer_, session_id);
    r["session"] = session_id;
  } else if (cmd == "apply") {
    const service::ApplyRequest apply = parseApplyRequest(request);
    const auto session_id = session.apply(apply);
    hub_->log_->warn("{}: applying session {} to the controller", peer_, session_id);
    r["session"] = session_id;
  } else if (cmd == "verify") {
    const auto session_id = session.verify(parseVerifyRequest(request));
    hub_->log_->info("{}: verifying session {}", peer_, session_id);
    r["session"] = session_id;
  } else if (cmd == "acknowledge") {
    const auto session_id = session.acknowledge(parseAcknowledgeRequest(request));
    hub_->log_->warn("{}: acknowledged the interrupted apply of session {}", peer_, session_id);
    r["session"] = session_id;
  } else if (cmd == "abort") {
    const bool aborted = session.abort();
    if (aborted) hub_->log_->warn("{}: aborted the session", peer_);
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
    hub_->startStatusTimer();
    r["status"] = toJson(session.status());  // the state the events that follow start from
  } else if (cmd == "unsubscribe") {
    subscribed_ = false;
  } else if (cmd == "psd") {
    readPsd(id);
    return false;
  } else if (cmd == "plan") {
    const auto plan = planFileInPlanDir(parseStartRequest(request, hub_->default_request_), request,
                                        options.plan_dir);
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

bool LineConnection::authFailure(const json& id, const char* error_code,
                                 const std::string& message) {
  ++auth_failures_;
  const bool last = auth_failures_ >= hub_->options_.max_auth_failures;
  hub_->log_->warn("{}: authentication failed ({}, {} of {}){}", peer_, error_code, auth_failures_,
                   hub_->options_.max_auth_failures, last ? "; closing" : "");
  auto response = errorResponse(id, error_code, last ? message + "; closing" : message);
  // The answer waits, so that guessing costs time; the connection reads nothing meanwhile.
  delay_.expires_after(hub_->options_.auth_failure_delay);
  delay_.async_wait([self = shared_from_this(), response, last](boost::system::error_code ec) {
    if (ec || self->closed_) return;
    if (last) return self->sendAndClose(response);
    self->send(response);
    self->read();
  });
  return false;
}

void LineConnection::readPsd(const json& id) {
  auto executor = hub_->io_.get_executor();
  std::weak_ptr<LineConnection> weak = shared_from_this();
  hub_->session_.readPsd(
      [executor, weak, id](std::optional<service::LiveReading> reading, const std::string& error) {
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
bool LineConnection::answerAside(const json& id, std::function<json()> work) {
  auto& server = *hub_;
  if (server.pending_previews_.fetch_add(1) >= server.options_.max_pending_previews) {
    server.pending_previews_.fetch_sub(1);
    send(errorResponse(id, "busy", "too many plans queued; try again shortly"));
    return true;
  }
  auto executor = server.io_.get_executor();
  std::weak_ptr<LineConnection> weak = shared_from_this();
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

void LineConnection::enqueue(const Line& line, bool answer) {
  if (closed_) return;
  std::size_t& queued = answer ? queued_answer_bytes_ : queued_event_bytes_;
  if ((!answer || queued > 0) && queued + line->size() > hub_->options_.max_queued_bytes) {
    hub_->log_->warn("{}: dropped, it does not read ({} bytes of {} queued)", peer_, queued,
                     answer ? "answers" : "events");
    close();
    return;
  }
  queued += line->size();
  queue_.push_back({line, answer});
  if (!writing_) writeNext();
}

void LineConnection::armWatchdog() {
  const auto& o = hub_->options_;
  const auto tick = std::min({std::chrono::milliseconds(1000), o.idle_timeout / 4,
                              o.write_timeout / 4, o.auth_timeout / 4});
  watchdog_.expires_after(std::max(tick, std::chrono::milliseconds(1)));
  watchdog_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (ec || self->closed_) return;
    self->checkTimeouts();
  });
}

void LineConnection::checkTimeouts() {
  const auto& o = hub_->options_;
  const auto now = Clock::now();
  if (!authenticated() && !closing_ && now - connected_at_ > o.auth_timeout) {
    hub_->log_->info("{}: not authenticated within {} ms; closing", peer_, o.auth_timeout.count());
    sendAndClose(errorResponse(nullptr, code::kUnauthenticated,
                               "authenticate within " + std::to_string(o.auth_timeout.count()) +
                                   " ms of connecting; closing"));
    if (closed_) return;
  }
  if (writing_ && now - write_started_ > o.write_timeout) {
    hub_->log_->warn("{}: dropped, a write was stuck for over {} ms", peer_,
                     o.write_timeout.count());
    return close();
  }
  // Idle: no complete line for idle_timeout. A half-open peer, or one trickling a line byte by
  // byte, never completes one. Subscribers and connections waiting for an answer are exempt.
  if (!subscribed_ && !closing_ && now - last_line_ > o.idle_timeout) {
    hub_->log_->info("{}: idle for {} ms; closing", peer_, o.idle_timeout.count());
    sendAndClose({{"event", "closing"}, {"reason", "idle timeout"}});
    if (closed_) return;
  }
  if (!closing_) {
    if (const std::string why = revoked(); !why.empty()) {
      hub_->log_->info("{}: {}; closing", peer_, why);
      sendAndClose({{"event", "closing"}, {"reason", why}});
      if (closed_) return;
    }
  }
  armWatchdog();
}

}  // namespace zerocal::control
