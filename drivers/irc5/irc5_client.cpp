#include "zerocal/irc5/irc5_client.h"

#include <fmt/format.h>

#include <algorithm>
#include <boost/asio.hpp>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "zerocal/irc5/motion_time.h"
#include "zerocal/irc5/protocol.h"

namespace zerocal {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

namespace {

// Replies are at most 80 characters; anything much longer is not a reply of this protocol.
constexpr std::size_t kMaxReplyBytes = 1024;

double parseNumber(std::string_view field, int code) {
  // The field is a view into a NUL-terminated line and ends at a space or the NUL, where strtod
  // stops too.
  char* end = nullptr;
  const double v = std::strtod(field.data(), &end);
  if (end != field.data() + field.size() || field.empty() || !std::isfinite(v)) {
    throw ProtocolError("reply to " + std::to_string(code) + ": \"" + std::string(field) +
                        "\" is not a number");
  }
  return v;
}

std::array<double, 6> sixNumbers(const irc5::ReplyView& r) {
  std::array<double, 6> out{};
  for (int i = 0; i < 6; ++i) out[i] = parseNumber(r.fields[i], r.code);
  return out;
}

// Memory for the one asynchronous operation in flight at a time, as in Asio's allocation example:
// a request then allocates nothing. A larger or a second operation falls back to the heap.
class HandlerMemory {
 public:
  void* allocate(std::size_t size) {
    if (!in_use_ && size <= sizeof storage_) {
      in_use_ = true;
      return storage_;
    }
    return ::operator new(size);
  }
  void deallocate(void* p) noexcept {
    if (p == storage_) {
      in_use_ = false;
    } else {
      ::operator delete(p);
    }
  }

 private:
  alignas(std::max_align_t) unsigned char storage_[1024];
  bool in_use_ = false;
};

template <typename T>
class HandlerAllocator {
 public:
  using value_type = T;
  explicit HandlerAllocator(HandlerMemory& memory) noexcept : memory_(&memory) {}
  template <typename U>
  HandlerAllocator(const HandlerAllocator<U>& other) noexcept : memory_(other.memory_) {}
  T* allocate(std::size_t n) { return static_cast<T*>(memory_->allocate(sizeof(T) * n)); }
  void deallocate(T* p, std::size_t) noexcept { memory_->deallocate(p); }
  template <typename U>
  bool operator==(const HandlerAllocator<U>& other) const noexcept {
    return memory_ == other.memory_;
  }
  template <typename U>
  bool operator!=(const HandlerAllocator<U>& other) const noexcept {
    return memory_ != other.memory_;
  }

 private:
  template <typename>
  friend class HandlerAllocator;
  HandlerMemory* memory_;
};

// A completion handler whose operation's memory comes from HandlerMemory (Asio asks
// get_allocator(), and composed operations pass it on to the operations they start).
template <typename Handler>
class WithMemory {
 public:
  using allocator_type = HandlerAllocator<Handler>;
  WithMemory(HandlerMemory& memory, Handler handler)
      : memory_(memory), handler_(std::move(handler)) {}
  allocator_type get_allocator() const noexcept { return allocator_type(memory_); }
  template <typename... Args>
  void operator()(Args&&... args) {
    handler_(std::forward<Args>(args)...);
  }

 private:
  HandlerMemory& memory_;
  Handler handler_;
};

}  // namespace

// The blocking-with-deadline pattern of Asio's blocking_tcp_client example: start an async
// operation, run the io_context for at most the time left, cancel what is still pending.
//
// A request and its reply allocate nothing once connected: the request is formatted into
// `request`, the reply read into `rx` and moved to `line` (both keep their reserved capacity),
// parsed in place, and the operations' memory is `memory`.
struct Irc5Client::Io {
  Io() {
    request.reserve(2 * irc5::kMaxMessageLength);
    rx.reserve(kMaxReplyBytes);
    line.reserve(kMaxReplyBytes);
  }

  asio::io_context ctx;
  tcp::socket socket{ctx};
  std::string request;
  std::string rx;
  std::string line;  // the last reply, without its LF; the last ReplyView looks into it
  HandlerMemory memory;
  bool open = false;

  template <typename Handler>
  WithMemory<Handler> handler(Handler h) {
    return WithMemory<Handler>(memory, std::move(h));
  }

  // Returns false when the deadline passed; pending operations are then cancelled and have
  // completed (with operation_aborted) before this returns.
  bool runUntil(Clock::time_point deadline) {
    ctx.restart();
    ctx.run_until(deadline);
    if (ctx.stopped()) return true;
    error_code ignored;
    socket.cancel(ignored);
    ctx.restart();
    ctx.run();
    return false;
  }

  void shut() {
    error_code ignored;
    socket.shutdown(tcp::socket::shutdown_both, ignored);
    socket.close(ignored);
    rx.clear();
    open = false;
  }
};

Irc5Client::Irc5Client(Irc5Options options) : options_(std::move(options)), io_(new Io) {
  std::vector<std::string> problems;
  for (int i = 0; i < kJointCount; ++i) {
    const JointLimit& l = options_.robot.limits[i];
    if (!(l.lower_deg < l.upper_deg)) {
      problems.push_back("robot joint " + std::to_string(i + 1) +
                         " has no usable limits: pass the robot file");
      break;
    }
  }
  if (options_.host.empty()) problems.push_back("host is empty");
  if (options_.limit_margin_deg < 0) problems.push_back("limit_margin_deg is negative");
  if (options_.max_step_deg < 0) problems.push_back("max_step_deg is negative");
  if (options_.connect_timeout.count() <= 0 || options_.request_timeout.count() <= 0 ||
      options_.move_timeout_margin.count() < 0 || options_.move_timeout_factor < 1.0) {
    problems.push_back("timeouts must be positive and move_timeout_factor at least 1");
  }
  if (!(options_.speed_tcp_mm_s > 0) || !(options_.speed_ori_deg_s > 0)) {
    problems.push_back("speed_tcp_mm_s and speed_ori_deg_s must be positive");
  }
  if (options_.reconnect_attempts < 1) problems.push_back("reconnect_attempts must be >= 1");
  if (options_.restart_timeout.count() <= 0) problems.push_back("restart_timeout must be > 0");
  if (!problems.empty()) throw ConfigError("Irc5Options", problems);
}

Irc5Client::~Irc5Client() { close(); }

bool Irc5Client::connected() const noexcept { return io_->open; }

void Irc5Client::connect() {
  io_->shut();
  have_joints_ = false;
  search_ready_ = false;
  error_code ec;
  tcp::resolver resolver(io_->ctx);
  const auto endpoints = resolver.resolve(options_.host, std::to_string(options_.port), ec);
  if (ec) throw ConnectionError("cannot resolve " + options_.host + ": " + ec.message());
  ec = asio::error::would_block;
  asio::async_connect(io_->socket, endpoints,
                      [&](const error_code& e, const tcp::endpoint&) { ec = e; });
  const std::string where = options_.host + ":" + std::to_string(options_.port);
  if (!io_->runUntil(Clock::now() + options_.connect_timeout)) {
    io_->shut();
    throw TimeoutError("no connection to " + where + " within " +
                       std::to_string(options_.connect_timeout.count()) + " ms");
  }
  if (ec) {
    io_->shut();
    throw ConnectionError("cannot connect to " + where + ": " + ec.message());
  }
  // Each request leaves in one segment at once; Nagle would hold small writes back.
  io_->socket.set_option(tcp::no_delay(true), ec);
  io_->open = true;
  try {
    using irc5::Param;
    ping();
    info_ = robotInfo();
    constexpr int q = irc5::kQuatDecimals, x = irc5::kXyzDecimals;
    const std::array<Param, 7> identity = {
        {{0, x}, {0, x}, {0, x}, {1, q}, {0, q}, {0, q}, {0, q}}};
    const auto rt = options_.request_timeout;
    transact(request(irc5::kSetTool, identity.data(), identity.size()), irc5::kSetTool, 0, rt);
    transact(request(irc5::kSetWorkObject, identity.data(), identity.size()), irc5::kSetWorkObject,
             0, rt);
    constexpr int s = irc5::kSpeedDecimals;
    transact(request(irc5::kSetSpeed, {{options_.speed_tcp_mm_s, s},
                                       {options_.speed_ori_deg_s, s},
                                       {options_.speed_leax_mm_s, s},
                                       {options_.speed_reax_deg_s, s}}),
             irc5::kSetSpeed, 0, rt);
    // Fine point: a move reply then means the robot stopped at the target, not fly-by.
    transact(request(irc5::kSetZone, {{1, 0}, {0, 0}, {0, 0}, {0, 0}}), irc5::kSetZone, 0, rt);
    checkRobotFileAgainst(readJointBounds());
  } catch (...) {
    io_->shut();
    throw;
  }
}

void Irc5Client::checkRobotFileAgainst(const std::array<JointLimit, kJointCount>& bounds) const {
  // Every move is checked against the robot file before it is sent; that check is worth only as
  // much as the file. A file wider than the controller's own bounds is refused outright.
  constexpr double kTolerance = 1e-3;  // the bounds travel with 3 decimals
  std::vector<std::string> problems;
  for (int i = 0; i < kJointCount; ++i) {
    const JointLimit& file = options_.robot.limits[i];
    if (file.lower_deg < bounds[i].lower_deg - kTolerance ||
        file.upper_deg > bounds[i].upper_deg + kTolerance) {
      problems.push_back(fmt::format(FMT_STRING("joint {}: the robot file allows {:.3f}..{:.3f} "
                                                "deg, the controller only {:.3f}..{:.3f} deg"),
                                     i + 1, file.lower_deg, file.upper_deg, bounds[i].lower_deg,
                                     bounds[i].upper_deg));
    }
  }
  if (!problems.empty())
    throw ConfigError("the robot file " + options_.robot.name + " is wider than the controller",
                      problems);
}

void Irc5Client::reconnect() {
  io_->shut();
  auto backoff = options_.backoff_initial;
  std::exception_ptr last;
  for (int attempt = 1; attempt <= options_.reconnect_attempts; ++attempt) {
    try {
      connect();
      return;
    } catch (const LinkError&) {
      last = std::current_exception();
    }
    if (attempt == options_.reconnect_attempts) break;
    // A controller restarting its server needs a moment; hammering it does not help.
    std::this_thread::sleep_for(backoff);
    backoff = std::min(backoff * 2, options_.backoff_max);
  }
  std::rethrow_exception(last);
}

void Irc5Client::close() noexcept {
  if (io_->open) {
    const std::string_view bye = request(irc5::kClose);
    io_->ctx.restart();
    asio::async_write(io_->socket, asio::buffer(bye.data(), bye.size()),
                      io_->handler([](const error_code&, std::size_t) {}));
    io_->runUntil(Clock::now() + milliseconds(200));
  }
  io_->shut();
  have_joints_ = false;
}

std::string_view Irc5Client::request(int code, std::initializer_list<irc5::Param> params) {
  return request(code, params.begin(), params.size());
}

std::string_view Irc5Client::request(int code, const irc5::Param* params, std::size_t count) {
  irc5::formatRequest(io_->request, code, params, count);
  return io_->request;
}

irc5::ReplyView Irc5Client::transact(std::string_view request, int code, int expected_fields,
                                     milliseconds timeout) {
  irc5::checkRequest(request);
  if (!io_->open) {
    throw ConnectionError("not connected to the controller (request " + std::string(request) + ")");
  }
  const auto deadline = Clock::now() + timeout;
  const auto fail = [&](auto error) {
    io_->shut();
    have_joints_ = false;
    throw error;
  };
  if (!io_->rx.empty()) {
    fail(ProtocolError("unsolicited bytes from the controller: \"" + io_->rx.substr(0, 60) + "\""));
  }

  error_code ec = asio::error::would_block;
  asio::async_write(io_->socket, asio::buffer(request.data(), request.size()),
                    io_->handler([&](const error_code& e, std::size_t) { ec = e; }));
  if (!io_->runUntil(deadline)) {
    fail(TimeoutError("timeout sending \"" + std::string(request) + "\""));
  }
  if (ec) {
    fail(ConnectionError("connection lost sending \"" + std::string(request) +
                         "\": " + ec.message()));
  }

  const auto timed_out = [&] {
    return TimeoutError("no complete reply to \"" + std::string(request) + "\" within " +
                        std::to_string(timeout.count()) + " ms (received \"" +
                        io_->rx.substr(0, 60) + "\")");
  };
  const auto dropped = [&](const error_code& e) {
    return ConnectionError(
        "connection lost waiting for the reply to \"" + std::string(request) +
        "\": " + (e == asio::error::eof ? "closed by the controller" : e.message()));
  };
  std::string& line = io_->line;
  if (options_.lf_terminated) {
    std::size_t n = 0;
    ec = asio::error::would_block;
    // Bounded, so that a stream that never sends LF cannot grow the buffer without limit.
    asio::async_read_until(io_->socket, asio::dynamic_buffer(io_->rx, kMaxReplyBytes), '\n',
                           io_->handler([&](const error_code& e, std::size_t bytes) {
                             ec = e;
                             n = bytes;
                           }));
    if (!io_->runUntil(deadline)) fail(timed_out());
    if (ec == asio::error::not_found) {
      fail(ProtocolError("no LF in the first " + std::to_string(kMaxReplyBytes) +
                         " bytes of the reply to \"" + std::string(request) + "\""));
    }
    if (ec) fail(dropped(ec));
    line.assign(io_->rx, 0, n - 1);
    io_->rx.erase(0, n);
  } else {
    char chunk[256];
    for (;;) {
      const auto state = irc5::replyCompleteness(io_->rx, expected_fields);
      if (state == irc5::Completeness::kComplete) break;
      const bool maybe = state == irc5::Completeness::kMaybe;
      const auto wait_until =
          maybe ? std::min(deadline, Clock::now() + options_.reply_settle) : deadline;
      std::size_t n = 0;
      ec = asio::error::would_block;
      io_->socket.async_read_some(asio::buffer(chunk),
                                  io_->handler([&](const error_code& e, std::size_t b) {
                                    ec = e;
                                    n = b;
                                  }));
      const bool in_time = io_->runUntil(wait_until);
      io_->rx.append(chunk, n);
      if (!in_time) {
        if (maybe && n == 0) break;  // nothing more came: the last field was complete
        if (Clock::now() >= deadline) fail(timed_out());
        continue;
      }
      if (ec) {
        if (maybe && ec == asio::error::eof) break;
        fail(dropped(ec));
      }
    }
    line.assign(io_->rx);
    io_->rx.clear();
  }

  irc5::ReplyView reply;
  try {
    reply = irc5::parseReplyView(line);
  } catch (const ProtocolError& e) {
    fail(e);
  }
  if (reply.code != code) {
    fail(ProtocolError("reply \"" + line + "\" answers code " + std::to_string(reply.code) +
                       ", not " + std::to_string(code) + " (stream out of step)"));
  }
  if (!reply.ok) throw BadMessageError(code, std::string(reply.data));
  if (expected_fields >= 0 && reply.field_count != static_cast<std::size_t>(expected_fields)) {
    fail(ProtocolError("reply \"" + line + "\" has " + std::to_string(reply.field_count) +
                       " data fields, expected " + std::to_string(expected_fields)));
  }
  return reply;
}

std::string Irc5Client::rawRequest(const std::string& request, int expected_fields,
                                   milliseconds timeout) {
  const irc5::ParsedRequest parsed = irc5::parseRequest(request);
  return std::string(transact(request, parsed.code, expected_fields, timeout).data);
}

void Irc5Client::ping() {
  transact(request(irc5::kPing), irc5::kPing, 0, options_.request_timeout);
}

RobotInfo Irc5Client::robotInfo() {
  const std::string data(
      transact(request(irc5::kRobotInfo), irc5::kRobotInfo, -1, options_.request_timeout).data);
  RobotInfo info;
  const std::size_t a = data.find('*');
  const std::size_t b = a == std::string::npos ? a : data.find('*', a + 1);
  if (b == std::string::npos) throw ProtocolError("robot info \"" + data + "\" lacks two '*'");
  info.serial = data.substr(0, a);
  info.software_version = data.substr(a + 1, b - a - 1);
  info.robot_type = data.substr(b + 1);
  return info;
}

Joints Irc5Client::readJoints() {
  const auto v = sixNumbers(
      transact(request(irc5::kReadJoints), irc5::kReadJoints, 6, options_.request_timeout));
  Joints q;
  std::copy(v.begin(), v.end(), q.begin());
  last_joints_ = q;
  have_joints_ = true;
  return q;
}

milliseconds Irc5Client::jointMoveTimeout(const Joints& from, const Joints& to) const {
  const double seconds = irc5::jointMoveSeconds(options_.robot, from, to, options_.speed_tcp_mm_s,
                                                options_.speed_ori_deg_s);
  return milliseconds(static_cast<long long>(seconds * options_.move_timeout_factor * 1000.0)) +
         options_.move_timeout_margin;
}

void Irc5Client::moveJoints(const Joints& target_deg) {
  for (int i = 0; i < kJointCount; ++i) {
    if (!std::isfinite(target_deg[i])) {
      throw RequestRefusedError("joint " + std::to_string(i + 1) + " target is not finite");
    }
  }
  const std::string violation =
      options_.robot.limitViolation(target_deg, options_.limit_margin_deg);
  if (!violation.empty()) throw RequestRefusedError("joint target refused: " + violation);
  // The step limit compares with where the robot is now (it may have been jogged since the last
  // read); the deadline alone can use the last known joints.
  if (!have_joints_ || options_.max_step_deg > 0) readJoints();
  const Joints from = last_joints_;
  if (options_.max_step_deg > 0) {
    for (int i = 0; i < kJointCount; ++i) {
      const double step = std::abs(target_deg[i] - from[i]);
      if (step > options_.max_step_deg) {
        throw RequestRefusedError("joint " + std::to_string(i + 1) + " step of " +
                                  std::to_string(step) + " deg exceeds the " +
                                  std::to_string(options_.max_step_deg) + " deg limit");
      }
    }
  }
  std::array<irc5::Param, kJointCount> params;
  for (int i = 0; i < kJointCount; ++i) params[i] = {target_deg[i], irc5::kJointDecimals};
  transact(request(irc5::kMoveJoints, params.data(), params.size()), irc5::kMoveJoints, 0,
           jointMoveTimeout(from, target_deg));
  last_joints_ = target_deg;
}

TcpPose Irc5Client::readPose() {
  const irc5::ReplyView r =
      transact(request(irc5::kReadPose), irc5::kReadPose, 7, options_.request_timeout);
  TcpPose p;
  for (int i = 0; i < 3; ++i) p.xyz_mm[i] = parseNumber(r.fields[i], r.code);
  for (int i = 0; i < 4; ++i) p.quat_wxyz[i] = parseNumber(r.fields[3 + i], r.code);
  return p;
}

void Irc5Client::moveLinear(const TcpPose& target) {
  TcpPose t = target;
  double norm = 0;
  for (double c : t.quat_wxyz) norm += c * c;
  norm = std::sqrt(norm);
  if (!(norm > 1e-9) || !std::isfinite(norm)) {
    throw RequestRefusedError("linear move target has a zero or non-finite quaternion");
  }
  for (double& c : t.quat_wxyz) c /= norm;
  for (double c : t.xyz_mm)
    if (!std::isfinite(c)) throw RequestRefusedError("linear move target is not finite");

  // Deadline from the path length and rotation angle at the configured speeds.
  const TcpPose from = readPose();
  double dist = 0, dot = 0;
  for (int i = 0; i < 3; ++i) dist += std::pow(t.xyz_mm[i] - from.xyz_mm[i], 2);
  for (int i = 0; i < 4; ++i) dot += t.quat_wxyz[i] * from.quat_wxyz[i];
  const double angle_deg = 2.0 * std::acos(std::min(1.0, std::abs(dot))) * 180.0 / M_PI;
  const double seconds =
      std::max(std::sqrt(dist) / options_.speed_tcp_mm_s, angle_deg / options_.speed_ori_deg_s);
  const auto timeout =
      milliseconds(static_cast<long long>(seconds * options_.move_timeout_factor * 1000.0)) +
      options_.move_timeout_margin;

  constexpr int x = irc5::kXyzDecimals, q = irc5::kQuatDecimals;
  have_joints_ = false;
  transact(request(irc5::kMoveLinear, {{t.xyz_mm[0], x},
                                       {t.xyz_mm[1], x},
                                       {t.xyz_mm[2], x},
                                       {t.quat_wxyz[0], q},
                                       {t.quat_wxyz[1], q},
                                       {t.quat_wxyz[2], q},
                                       {t.quat_wxyz[3], q}}),
           irc5::kMoveLinear, 0, timeout);
}

bool Irc5Client::startSpotSearch(const SpotSearch& search) {
  search_ready_ = false;
  if (!(search.pitch_mm > 0)) throw RequestRefusedError("spot search pitch must be positive");
  const Joints* rows[3] = {&search.centre_deg, &search.per_u_mm, &search.per_v_mm};
  for (int row = 0; row < 3; ++row) {
    // Joints at 5 decimals, as every joint; the rows of deg per mm at 6 (~1e-6 deg/mm leaves
    // under 0.1 um of spot at 60 mm).
    const int decimals = row == 0 ? irc5::kJointDecimals : 6;
    std::array<irc5::Param, 7> params;
    params[0] = {static_cast<double>(row), 0};
    for (int i = 0; i < kJointCount; ++i) {
      if (!std::isfinite((*rows[row])[i]))
        throw RequestRefusedError("spot search row " + std::to_string(row) + " is not finite");
      params[1 + i] = {(*rows[row])[i], decimals};
    }
    try {
      transact(request(irc5::kSearchSpiral, params.data(), params.size()), irc5::kSearchSpiral, 0,
               options_.request_timeout);
    } catch (const BadMessageError&) {
      if (row == 0) return false;  // upstream's server, or a module without its light signal
      throw;
    }
  }
  search_ = search;
  search_ready_ = true;
  return true;
}

std::optional<Joints> Irc5Client::searchRun(const SearchRun& run) {
  if (!search_ready_) throw RequestRefusedError("search run without a search spiral");
  if (!(run.from_mm >= 0) || !(run.to_mm >= run.from_mm) || !std::isfinite(run.to_mm))
    throw RequestRefusedError("search run radii must satisfy 0 <= from <= to");
  if (!(run.speed_mm_s > 0) || run.speed_mm_s > options_.speed_tcp_mm_s)
    throw RequestRefusedError("search speed " + std::to_string(run.speed_mm_s) +
                              " mm/s is not in (0, the link's TCP speed " +
                              std::to_string(options_.speed_tcp_mm_s) + " mm/s]");
  // Every waypoint, and every step to it, as a joint move would be checked; the deadline from
  // the same steps at the run's speed.
  if (!have_joints_ || options_.max_step_deg > 0) readJoints();
  Joints from = last_joints_;
  double seconds = 0;
  const char* problem = nullptr;
  int waypoints = 0;
  forEachSearchWaypoint(search_, run, [&](const Joints& q) {
    ++waypoints;
    if (!options_.robot.withinLimits(q, options_.limit_margin_deg)) {
      problem = "a waypoint lies outside the joint limits less the margin";
      return false;
    }
    for (int i = 0; i < kJointCount; ++i) {
      if (options_.max_step_deg > 0 && std::abs(q[i] - from[i]) > options_.max_step_deg) {
        problem = "a step between waypoints exceeds the step limit";
        return false;
      }
    }
    seconds +=
        irc5::jointMoveSeconds(options_.robot, from, q, run.speed_mm_s, options_.speed_ori_deg_s);
    from = q;
    return true;
  });
  if (problem != nullptr) throw RequestRefusedError(std::string("search run refused: ") + problem);
  if (waypoints == 0) throw RequestRefusedError("search run has no waypoint");
  const std::array<irc5::Param, 4> params{{{search_.pitch_mm, 3},
                                           {run.from_mm, 3},
                                           {run.to_mm, 3},
                                           {run.speed_mm_s, irc5::kSpeedDecimals}}};
  const auto timeout =
      milliseconds(static_cast<long long>(seconds * options_.move_timeout_factor * 1000.0)) +
      options_.move_timeout_margin;
  have_joints_ = false;  // somewhere on the spiral
  const irc5::ReplyView r = transact(request(irc5::kSearchRun, params.data(), params.size()),
                                     irc5::kSearchRun, -1, timeout);
  if (r.field_count == 1 && r.fields[0] == "0") return std::nullopt;
  if (r.field_count != 7 || r.fields[0] != "1")
    throw ProtocolError("reply to 49 is neither \"0\" nor \"1\" and six joints: \"" +
                        std::string(r.data) + "\"");
  Joints hit;
  for (int i = 0; i < kJointCount; ++i) hit[i] = parseNumber(r.fields[1 + i], r.code);
  return hit;
}

void Irc5Client::stop() {
  transact(request(irc5::kStop), irc5::kStop, 0, options_.request_timeout);
}

std::array<double, 6> Irc5Client::readExternalAxes() {
  return sixNumbers(transact(request(irc5::kReadExternalAxes), irc5::kReadExternalAxes, 6,
                             options_.request_timeout));
}

std::array<double, 6> Irc5Client::readCalOffsets() {
  return sixNumbers(
      transact(request(irc5::kReadCalOffset), irc5::kReadCalOffset, 6, options_.request_timeout));
}

void Irc5Client::writeCalOffset(int joint, double rad) {
  transact(request(irc5::kWriteCalOffset, {{double(joint), 0}, {rad, 6}}), irc5::kWriteCalOffset, 0,
           options_.request_timeout);
}

std::array<double, 6> Irc5Client::readMotorAngles() {
  return sixNumbers(transact(request(irc5::kReadMotorAngles), irc5::kReadMotorAngles, 6,
                             options_.request_timeout));
}

void Irc5Client::restartController() {
  transact(request(irc5::kRestart), irc5::kRestart, 0, options_.request_timeout);
  // The controller goes away now and refuses or ignores connections until its restart is over:
  // a few attempts (reconnect()) would give up long before a warm start ends.
  io_->shut();
  have_joints_ = false;
  const auto deadline = Clock::now() + options_.restart_timeout;
  auto backoff = options_.backoff_initial;
  for (;;) {
    std::this_thread::sleep_for(backoff);
    try {
      connect();
      return;
    } catch (const LinkError& e) {
      if (e.kind() != LinkError::Kind::kTransient) throw;
      if (Clock::now() + backoff >= deadline)
        throw TimeoutError("the controller did not serve again within " +
                           std::to_string(options_.restart_timeout.count()) +
                           " ms of its restart: " + e.what());
    }
    backoff = std::min(backoff * 2, options_.backoff_max);
  }
}

std::array<JointLimit, kJointCount> Irc5Client::readJointBounds() {
  const auto lower = sixNumbers(transact(request(irc5::kReadJointBounds, {{0, 0}}),
                                         irc5::kReadJointBounds, 6, options_.request_timeout));
  const auto upper = sixNumbers(transact(request(irc5::kReadJointBounds, {{1, 0}}),
                                         irc5::kReadJointBounds, 6, options_.request_timeout));
  std::array<JointLimit, kJointCount> out;
  for (int i = 0; i < kJointCount; ++i) out[i] = {lower[i], upper[i]};
  return out;
}

std::optional<PsdSpot> Irc5Client::readSimBeamSpot() {
  const irc5::ReplyView r =
      transact(request(irc5::kSimBeamSpot), irc5::kSimBeamSpot, 3, options_.request_timeout);
  if (parseNumber(r.fields[0], r.code) == 0) return std::nullopt;
  return PsdSpot{parseNumber(r.fields[1], r.code), parseNumber(r.fields[2], r.code)};
}

SimWorldId Irc5Client::readSimWorldId() {
  const irc5::ReplyView r =
      transact(request(irc5::kSimWorldId), irc5::kSimWorldId, 2, options_.request_timeout);
  SimWorldId id;
  id.hash = std::string(r.fields[0]);
  const std::string seed(r.fields[1]);
  char* end = nullptr;
  id.seed = std::strtoull(seed.c_str(), &end, 10);
  if (end == seed.c_str() || *end != '\0')
    throw ProtocolError("reply to 44: seed \"" + seed + "\" is not a number");
  return id;
}

}  // namespace zerocal
