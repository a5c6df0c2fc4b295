#include "zerocal/sim/sim_controller.h"

#include <fmt/format.h>

#include <algorithm>
#include <boost/asio.hpp>
#include <cmath>
#include <cstdio>
#include <deque>
#include <mutex>
#include <set>
#include <thread>

#include "zerocal/cell/search_move.h"
#include "zerocal/error.h"
#include "zerocal/irc5/motion_time.h"
#include "zerocal/irc5/protocol.h"

namespace zerocal {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;
using std::chrono::milliseconds;

sim::MotionModel irc5MotionModel(const irc5::MotionCosts& costs) {
  sim::MotionModel m;
  m.cruise_s = [](const Robot& robot, const Joints& from, const Joints& to,
                  const sim::MoveSpeed& speed) {
    return irc5::jointMoveSeconds(robot, from, to, speed.tcp_mm_s, speed.ori_deg_s);
  };
  m.profile_s = [accel = costs.joint_accel_deg_s2](double cruise_s, double largest_joint_deg) {
    return irc5::rampedSeconds(cruise_s, largest_joint_deg, accel);
  };
  m.overhead_s = costs.overhead_s;
  m.settle_s = costs.settle_s;
  return m;
}

namespace {

// RAPID's num is a 32-bit float: every number the module parses or returns goes through this
// (the arm rounds what it stores, SimulatedArmOptions::single_precision).
double f32(double v) { return sim::roundToFloat32(v); }

std::string fixed(double v, int decimals) {
  // Values that round to zero print as "0.000", never "-0.000".
  if (std::abs(v) < 0.5 * std::pow(10.0, -decimals)) v = 0.0;
  return fmt::format(FMT_STRING("{:.{}f}"), v, decimals);
}

// Seven parameters (x, y, z, qw, qx, qy, qz) as RAPID parses them.
TcpPose poseOf(const std::vector<double>& p) {
  TcpPose pose;
  for (int i = 0; i < 3; ++i) pose.xyz_mm[i] = f32(p[i]);
  for (int i = 0; i < 4; ++i) pose.quat_wxyz[i] = f32(p[3 + i]);
  return pose;
}

// The arm of the options, with the world moved into it (SimController::world() is the arm's).
// The options' errors keep the name their users know.
std::unique_ptr<sim::SimulatedArm> makeArm(SimControllerOptions& o) {
  const std::string motion = o.motion.validate();
  if (!motion.empty()) throw ConfigError("SimControllerOptions", {"motion: " + motion});
  sim::SimulatedArmOptions a;
  a.world = std::move(o.world);
  a.motor = o.motor;
  a.search = o.search;
  a.motion = irc5MotionModel(o.motion);
  a.restart_s = o.restart_s;
  a.warm_s = o.warm_s;
  a.seed = o.seed;
  a.start_joints = o.start_joints;
  a.single_precision = true;  // RAPID's num
  a.identity = RobotInfo{o.serial, o.software_version, o.robot_type};
  try {
    return std::make_unique<sim::SimulatedArm>(std::move(a));
  } catch (const ConfigError& e) {
    throw ConfigError("SimControllerOptions", e.problems());
  }
}

}  // namespace

struct SimController::Impl {
  class Session;

  explicit Impl(SimControllerOptions o)
      : options(std::move(o)), arm(makeArm(options)), acceptor(ctx), faults(options.faults) {
    error_code ec;
    const tcp::endpoint ep(asio::ip::make_address(options.address, ec), options.port);
    if (ec) throw Error("simulated controller: bad address " + options.address);
    listen(ep, ec);
    if (ec) {
      throw Error("simulated controller: cannot listen on " + options.address + ":" +
                  std::to_string(options.port) + ": " + ec.message());
    }
    endpoint = acceptor.local_endpoint();  // the port stays this one across restarts
  }

  void listen(const tcp::endpoint& ep, error_code& ec) {
    acceptor.open(ep.protocol(), ec);
    if (!ec) acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
    if (!ec) acceptor.bind(ep, ec);
    if (!ec) acceptor.listen(asio::socket_base::max_listen_connections, ec);
    if (ec) {
      error_code ignored;
      acceptor.close(ignored);
    }
  }

  void accept();
  void closeAll();

  // The reply text (without terminator) to one request, or nullopt for no reply (99). Also
  // returns, through wall_delay, how long a paced move takes. I/O thread.
  std::optional<std::string> respond(const irc5::ParsedRequest& r, milliseconds* wall_delay);
  // A move's reply; paced, its cost in wall time through wall_delay.
  std::string moved(int code, const sim::MoveResult& result, milliseconds* wall_delay) const;
  // The restart after 46 has been answered: the arm restarted (written cal_offsets taken, its
  // clock charged), every connection dropped; when paced, the listener closed for pace x
  // restart_s of wall time (connections refused), as a restarting controller's. I/O thread.
  void restart();
  // Listens again at the end of a restart. I/O thread.
  void relisten();

  SimControllerOptions options;  // its world moved into the arm
  std::unique_ptr<sim::SimulatedArm> arm;
  asio::io_context ctx;
  tcp::acceptor acceptor;
  tcp::endpoint endpoint;                 // where it listens
  asio::steady_timer restart_timer{ctx};  // the end of a restart (I/O thread)
  bool stopped = false;                   // I/O thread
  std::thread thread;
  std::set<std::shared_ptr<Session>> sessions;  // I/O thread only

  // The RAPID module's own state between requests. I/O thread only.
  SpotSearch search;    // the spiral given by 47
  int search_rows = 0;  // bit r: row r of 47 received
  bool restart_requested = false;

  mutable std::mutex mutex;  // guards the three below
  SimFaults faults;
  long requests = 0, connections = 0;
};

class SimController::Impl::Session : public std::enable_shared_from_this<Session> {
 public:
  // impl outlives every session: it owns the io_context whose handlers hold the sessions.
  Session(Impl* impl, tcp::socket socket)
      : impl_(impl), socket_(std::move(socket)), timer_(impl_->ctx), partial_timer_(impl_->ctx) {}

  void start() {
    error_code ignored;
    socket_.set_option(tcp::no_delay(true), ignored);  // so that split replies stay split
    handleNext();
  }

  void close() {
    error_code ignored;
    socket_.shutdown(tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
    timer_.cancel();
    partial_timer_.cancel();
    impl_->sessions.erase(shared_from_this());
  }

 private:
  void handleNext() {
    if (writing_ || !socket_.is_open()) return;
    if (stalled_) {
      // Blocked "inside a move": ignore requests but keep reading, to notice the client leave.
      rx_.clear();
      readMore();
      return;
    }
    // Stray whitespace between requests (a client's LF after '#') must not desynchronise us.
    const std::size_t start = rx_.find_first_not_of(" \r\n\t");
    rx_.erase(0, start == std::string::npos ? rx_.size() : start);
    const std::size_t hash = rx_.find('#');
    if (hash == std::string::npos) {
      if (!rx_.empty()) armPartialTimer();
      readMore();
      return;
    }
    partial_timer_.cancel();
    partial_armed_ = false;
    const std::string request = rx_.substr(0, hash + 1);
    rx_.erase(0, hash + 1);
    process(request);
  }

  void readMore() {
    if (reading_) return;
    reading_ = true;
    auto self = shared_from_this();
    socket_.async_read_some(asio::buffer(chunk_),
                            [this, self](const error_code& ec, std::size_t n) {
                              reading_ = false;
                              if (ec) {
                                if (ec != asio::error::operation_aborted) close();
                                return;
                              }
                              rx_.append(chunk_, n);
                              handleNext();
                            });
  }

  void armPartialTimer() {
    if (partial_armed_) return;
    partial_armed_ = true;
    auto self = shared_from_this();
    partial_timer_.expires_after(impl_->options.partial_request_timeout);
    partial_timer_.async_wait([this, self](const error_code& ec) {
      partial_armed_ = false;
      if (ec || writing_ || rx_.empty() || rx_.find('#') != std::string::npos) return;
      // Answer the fragment as a bad message with its own code rather than let it merge with the
      // next request.
      const irc5::ParsedRequest r = irc5::parseRequest(rx_);
      rx_.clear();
      send(std::to_string(r.valid ? r.code : 0) + " 0 request without '#'", milliseconds(0));
    });
  }

  void process(const std::string& request) {
    SimFaults faults;
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      faults = impl_->faults;
      ++impl_->requests;
    }
    ++answered_;
    if (faults.drop_after_requests >= 0 && answered_ > faults.drop_after_requests) {
      close();
      return;
    }
    const irc5::ParsedRequest r = irc5::parseRequest(request);
    if (r.valid && r.code == faults.drop_code) {
      bool drop = false;
      {
        std::lock_guard<std::mutex> lock(impl_->mutex);
        drop = impl_->faults.drop_code == r.code && impl_->faults.drop_code_times > 0;
        if (drop) --impl_->faults.drop_code_times;
      }
      if (drop) {
        close();
        return;
      }
    }
    const bool move = r.valid && (r.code == irc5::kMoveJoints || r.code == irc5::kMoveLinear ||
                                  r.code == irc5::kSearchRun);
    if (move && faults.stall_moves) {
      stalled_ = true;
      return;
    }
    if (r.valid && r.code == faults.garbage_code) {
      send("#?!\x7f garbage", faults.reply_delay);
      return;
    }
    milliseconds pace(0);
    const std::optional<std::string> reply = impl_->respond(r, &pace);
    if (!reply) {
      close();  // 99: the server closes and listens again
      return;
    }
    send(*reply, faults.reply_delay + pace);
  }

  void send(std::string text, milliseconds delay) {
    if (impl_->options.lf_terminated) text += '\n';
    SimFaults faults;
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      faults = impl_->faults;
    }
    pieces_.clear();
    if (faults.split_replies && text.size() >= 3) {
      const std::size_t a = text.size() / 3, b = 2 * text.size() / 3;
      pieces_ = {text.substr(0, a), text.substr(a, b - a), text.substr(b)};
    } else {
      pieces_ = {text};
    }
    split_gap_ = faults.split_gap;
    writing_ = true;
    if (delay.count() > 0) {
      auto self = shared_from_this();
      timer_.expires_after(delay);
      timer_.async_wait([this, self](const error_code& ec) {
        if (ec) return;
        writePiece();
      });
    } else {
      writePiece();
    }
  }

  void writePiece() {
    auto self = shared_from_this();
    asio::async_write(socket_, asio::buffer(pieces_.front()),
                      [this, self](const error_code& ec, std::size_t) {
                        if (ec) {
                          close();
                          return;
                        }
                        pieces_.pop_front();
                        if (pieces_.empty()) {
                          writing_ = false;
                          impl_->restart();  // when 46 was just answered
                          if (socket_.is_open()) handleNext();
                          return;
                        }
                        timer_.expires_after(split_gap_);
                        timer_.async_wait([this, self](const error_code& e) {
                          if (!e) writePiece();
                        });
                      });
  }

  Impl* impl_;
  tcp::socket socket_;
  asio::steady_timer timer_;
  asio::steady_timer partial_timer_;
  char chunk_[512];
  std::string rx_;
  std::deque<std::string> pieces_;
  milliseconds split_gap_{0};
  bool reading_ = false, writing_ = false, stalled_ = false, partial_armed_ = false;
  int answered_ = 0;
};

void SimController::Impl::accept() {
  acceptor.async_accept([this](const error_code& ec, tcp::socket socket) {
    if (ec) return;  // closed by stop()
    {
      std::lock_guard<std::mutex> lock(mutex);
      ++connections;
    }
    auto session = std::make_shared<Session>(this, std::move(socket));
    sessions.insert(session);
    session->start();
    accept();
  });
}

void SimController::Impl::restart() {
  if (!restart_requested) return;
  restart_requested = false;
  search_rows = 0;  // the RAPID program starts over
  const double restart_s = arm->restart();
  milliseconds down(0);
  if (options.pace > 0)
    down = milliseconds(static_cast<long long>(restart_s * options.pace * 1000));
  const auto copy = sessions;
  for (const auto& s : copy) s->close();
  if (down.count() == 0 || stopped) return;
  // A restarting controller serves nothing: connecting is refused until it is back.
  error_code ignored;
  acceptor.close(ignored);
  restart_timer.expires_after(down);
  restart_timer.async_wait([this](const error_code& ec) {
    if (!ec) relisten();
  });
}

void SimController::Impl::relisten() {
  if (stopped) return;
  error_code ec;
  listen(endpoint, ec);
  if (ec) {
    // The port taken meanwhile (rare: an ephemeral port): try again shortly, as a controller's
    // server would.
    std::fprintf(stderr, "simulated controller: cannot listen again on port %u: %s\n",
                 static_cast<unsigned>(endpoint.port()), ec.message().c_str());
    restart_timer.expires_after(milliseconds(100));
    restart_timer.async_wait([this](const error_code& e) {
      if (!e) relisten();
    });
    return;
  }
  accept();
}

void SimController::Impl::closeAll() {
  stopped = true;
  restart_timer.cancel();
  error_code ignored;
  acceptor.close(ignored);
  const auto copy = sessions;
  for (const auto& s : copy) s->close();
}

std::string SimController::Impl::moved(int code, const sim::MoveResult& result,
                                       milliseconds* wall_delay) const {
  const std::string c = std::to_string(code);
  switch (result.refusal) {
    case sim::MoveRefusal::kNone:
      break;
    case sim::MoveRefusal::kOutOfLimits:
      return c + " 0 out of bounds";
    case sim::MoveRefusal::kUnreachable:
      return c + " 0 unreachable";
    case sim::MoveRefusal::kBadPath:
      return c + " 0 bad run";
    case sim::MoveRefusal::kNoSearchSignal:
      return c + " 0 no search signal";
  }
  if (options.pace > 0)
    *wall_delay = milliseconds(static_cast<long long>(result.cost.total() * options.pace * 1000));
  if (code != irc5::kSearchRun) return c + " 1 ";
  if (!result.latched_deg) return c + " 1 0";
  std::string reply = c + " 1 1";
  for (double v : *result.latched_deg) reply += " " + fixed(v, irc5::kJointDecimals);
  return reply;
}

std::optional<std::string> SimController::Impl::respond(const irc5::ParsedRequest& r,
                                                        milliseconds* wall_delay) {
  const std::string c = std::to_string(r.code);
  const std::string bad = c + " 0 ";
  const std::string done = c + " 1 ";
  if (!r.valid) return std::string("0 0 ");
  const std::size_t n = r.params.size();
  const auto six = [&](const std::array<double, 6>& v, int decimals) {
    std::string s = done;
    for (int i = 0; i < 6; ++i) s += fixed(v[i], decimals) + (i < 5 ? " " : "");
    return s;
  };
  switch (r.code) {
    case irc5::kPing:
      return n == 0 ? done : bad;
    case irc5::kMoveLinear:
      if (n != 7) return bad;
      return moved(r.code, arm->moveLinear(poseOf(r.params)), wall_delay);
    case irc5::kMoveJoints: {
      if (n != 6) return bad;
      Joints q;
      std::copy(r.params.begin(), r.params.end(), q.begin());
      return moved(r.code, arm->moveJoints(q), wall_delay);
    }
    case irc5::kReadPose: {
      if (n != 0) return bad;
      const TcpPose pose = arm->toolPose();
      std::string s = done;
      for (int i = 0; i < 3; ++i) s += fixed(f32(pose.xyz_mm[i]), irc5::kXyzDecimals) + " ";
      for (int i = 0; i < 4; ++i)
        s += fixed(f32(pose.quat_wxyz[i]), irc5::kQuatDecimals) + (i < 3 ? " " : "");
      return s;
    }
    case irc5::kReadJoints:
      return n == 0 ? six(arm->joints(), irc5::kJointDecimals) : bad;
    case irc5::kReadExternalAxes:
      // No external axes: RAPID reports 9E9 for unused ones.
      return n == 0 ? done + "9E+09 9E+09 9E+09 9E+09 9E+09 9E+09" : bad;
    case irc5::kSetTool:
      if (n != 7) return bad;
      arm->setTool(poseOf(r.params));
      return done;
    case irc5::kSetWorkObject:
      if (n != 7) return bad;
      arm->setWorkObject(poseOf(r.params));
      return done;
    case irc5::kSetSpeed:
      if (n != 4 && n != 2) return bad;
      if (!(r.params[0] > 0) || !(r.params[1] > 0)) return c + " 0 speeds must be positive";
      arm->setSpeed({f32(r.params[0]), f32(r.params[1])});
      return done;
    case irc5::kSetZone:
      // Every move of the arm ends at a fine point; the zone is checked, not kept.
      return n == 4 ? done : bad;
    case irc5::kStop:
      return n == 0 ? done : bad;  // a move has ended (simulated) before its reply
    case irc5::kReadCalOffset:
      // The configuration's values, written ones included, as ReadCfgData reads them.
      return n == 0 ? six(arm->configuredCalOffsets(), 6) : bad;
    case irc5::kWriteCalOffset: {
      if (n != 2) return bad;
      const double joint = r.params[0];
      if (!(joint >= 1 && joint <= kJointCount && joint == std::floor(joint))) return bad;
      switch (arm->configureCalOffset(static_cast<int>(joint), f32(r.params[1]))) {
        case sim::CalOffsetRefusal::kNone:
          return done;
        case sim::CalOffsetRefusal::kTransmissionUnknown:
          return c + " 0 transmission unknown";
        default:
          return bad;
      }
    }
    case irc5::kRestart:
      if (n != 0) return bad;
      restart_requested = true;
      return done;
    case irc5::kReadMotorAngles: {
      // ReadMotor: the motor's angle behind the joint angle the controller reports, q = (phi -
      // cal_offset) / k with the arm's true k, within one motor turn (docs/apply.md: inferred).
      if (n != 0) return bad;
      std::array<double, 6> phi = arm->motorAnglesRad();
      for (double& v : phi) v = f32(v);
      return six(phi, 6);
    }
    case irc5::kReadJointBounds: {
      if (n != 1 || (r.params[0] != 0 && r.params[0] != 1)) return bad;
      std::array<double, 6> b;
      for (int i = 0; i < 6; ++i) {
        const JointLimit& l = arm->world().robot.limits[i];
        b[i] = r.params[0] == 0 ? l.lower_deg : l.upper_deg;
      }
      return six(b, 3);
    }
    case irc5::kSearchSpiral: {
      // Row 0: the centre's joints; rows 1 and 2: the joints per mm of spot along u and v.
      if (n != 7 || !(r.params[0] == 0 || r.params[0] == 1 || r.params[0] == 2)) return bad;
      if (!arm->searchSignalWired()) return c + " 0 no search signal";
      const int row = static_cast<int>(r.params[0]);
      Joints& v = row == 0 ? search.centre_deg : row == 1 ? search.per_u_mm : search.per_v_mm;
      for (int i = 0; i < kJointCount; ++i) v[i] = f32(r.params[1 + i]);
      search_rows |= 1 << row;
      return done;
    }
    case irc5::kSearchRun: {
      if (n != 4) return bad;
      if (search_rows != 7) return c + " 0 no search spiral";
      const double pitch = f32(r.params[0]);
      const SearchRun run{f32(r.params[1]), f32(r.params[2]), f32(r.params[3])};
      if (!(pitch > 0) || !(run.from_mm >= 0) || !(run.to_mm >= run.from_mm) ||
          !(run.speed_mm_s > 0) || run.speed_mm_s > arm->speed().tcp_mm_s)
        return bad;
      search.pitch_mm = pitch;
      return moved(r.code, arm->searchRun(search, run), wall_delay);
    }
    case irc5::kSimBeamSpot: {
      // Simulator only: what a PSD placed in the world would see now (an external daemon's
      // simulated board asks this over its own connection).
      if (n != 0) return bad;
      const std::optional<BeamHit> hit = arm->beamHitNow();
      if (!hit || !hit->spot.finite() || std::abs(hit->spot.u_mm) > 1e6 ||
          std::abs(hit->spot.v_mm) > 1e6)
        return done + "0 0 0";
      return done + "1 " + fixed(hit->spot.u_mm, 5) + " " + fixed(hit->spot.v_mm, 5);
    }
    case irc5::kSimWorldId:
      return n == 0 ? done + worldHash(arm->world()) + " " + std::to_string(arm->seed()) : bad;
    case irc5::kRobotInfo: {
      if (n != 0) return bad;
      const RobotInfo& id = arm->identity();
      return done + id.serial + "*" + id.software_version + "*" + id.robot_type;
    }
    case irc5::kClose:
      return std::nullopt;
    default:
      if (r.code >= 30 && r.code <= 36) return c + " 0 not supported";
      return bad;
  }
}

SimController::SimController(SimControllerOptions options)
    : impl_(std::make_shared<Impl>(std::move(options))) {
  impl_->accept();
}

SimController::~SimController() {
  stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

void SimController::start() {
  impl_->thread = std::thread([impl = impl_] { impl->ctx.run(); });
}

void SimController::run(bool stop_on_signals) {
  asio::signal_set signals(impl_->ctx);
  if (stop_on_signals) {
    signals.add(SIGINT);
    signals.add(SIGTERM);
    signals.async_wait([this](const error_code& ec, int) {
      if (!ec) stop();
    });
  }
  impl_->ctx.run();
}

void SimController::stop() {
  // Closing everything lets run() return by itself; posted so that it runs on the I/O thread.
  asio::post(impl_->ctx, [impl = impl_] {
    impl->closeAll();
    impl->ctx.stop();
  });
  if (impl_->thread.joinable() && impl_->thread.get_id() != std::this_thread::get_id()) {
    impl_->thread.join();
  }
}

std::uint16_t SimController::port() const { return impl_->endpoint.port(); }

void SimController::setFaults(const SimFaults& faults) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->faults = faults;
}

Joints SimController::commandedJoints() const { return impl_->arm->joints(); }
Joints SimController::moveErrorDeg() const { return impl_->arm->moveErrorDeg(); }
std::optional<BeamHit> SimController::beamHitNow() const { return impl_->arm->beamHitNow(); }
std::array<double, kJointCount> SimController::calOffsets() const {
  return impl_->arm->calOffsets();
}
void SimController::writeCalOffset(int joint, double rad) { impl_->arm->takeCalOffset(joint, rad); }
void SimController::updateRevolutionCounter(int joint) {
  impl_->arm->updateRevolutionCounter(joint);
}
Joints SimController::zeroShiftDeg() const { return impl_->arm->zeroShiftDeg(); }
void SimController::reseedNoise(std::uint64_t seed) { impl_->arm->reseedNoise(seed); }
std::uint64_t SimController::noiseSeed() const { return impl_->arm->noiseSeed(); }
void SimController::placePsd(int placement,
                             const std::vector<Eigen::Vector3d>& planned_centres_mm) {
  impl_->arm->placePsd(placement, planned_centres_mm);
}
double SimController::simTimeS() const { return impl_->arm->timeS(); }
MotionTotals SimController::motionTotals() const { return impl_->arm->motionTotals(); }
long SimController::restartCount() const { return impl_->arm->restartCount(); }
const World& SimController::world() const { return impl_->arm->world(); }

long SimController::requestCount() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->requests;
}

long SimController::connectionCount() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->connections;
}

}  // namespace zerocal
