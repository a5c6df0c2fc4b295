#include "zerocal/sim/sim_controller.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <boost/asio.hpp>
#include <cmath>
#include <cstdio>
#include <deque>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "zerocal/cell/search_move.h"
#include "zerocal/error.h"
#include "zerocal/irc5/motion_time.h"
#include "zerocal/irc5/protocol.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;
using std::chrono::milliseconds;

namespace {

// RAPID's num is a 32-bit float: every stored number goes through this. The volatile store keeps
// the rounding: with a plain cast, GCC 12 at -O3 vectorised moveTo()'s loop and left the last
// two of six joints unrounded (caught by the float32 read-back test).
double f32(double v) {
  volatile float f = static_cast<float>(v);
  return static_cast<double>(f);
}

std::string fmt(double v, int decimals) {
  char buf[48];
  // Values that round to zero print as "0.000", never "-0.000".
  if (std::abs(v) < 0.5 * std::pow(10.0, -decimals)) v = 0.0;
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

Frame<double> frameOf(const std::vector<double>& p) {
  Frame<double> f;
  f.p = Eigen::Vector3d(p[0], p[1], p[2]);
  Eigen::Quaterniond q(p[3], p[4], p[5], p[6]);
  if (q.norm() < 1e-9) q = Eigen::Quaterniond::Identity();
  f.R = q.normalized().toRotationMatrix();
  return f;
}

Frame<double> inverse(const Frame<double>& f) { return {f.R.transpose(), -f.R.transpose() * f.p}; }

}  // namespace

struct SimController::Impl {
  class Session;

  explicit Impl(SimControllerOptions o)
      : options(std::move(o)),
        acceptor(ctx),
        rng(options.seed),
        gross_rng(options.seed ^ 0x67726f7373ull),
        search_rng(options.seed ^ 0x736561726368ull),
        faults(options.faults) {
    const std::string motion = options.motion.validate();
    if (!motion.empty()) throw ConfigError("SimControllerOptions", {"motion: " + motion});
    if (!(options.restart_s >= 0 && options.restart_s <= 3600))
      throw ConfigError("SimControllerOptions", {"restart_s must be within 0..3600 s"});
    commanded = options.start_joints;
    for (double& q : commanded) q = f32(q);
    initMotorCalibration();
    const std::string violation = options.world.robot.limitViolation(commanded);
    if (!violation.empty())
      throw ConfigError("SimControllerOptions", {"start joints: " + violation});
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
  void initMotorCalibration();
  // The true joint angles' excess over commanded + world offsets: the move's error plus how far
  // cal_offset changes have moved each zero (deg).
  Joints trueExtraDeg() const {
    Joints e;
    for (int i = 0; i < kJointCount; ++i) e[i] = move_error[i] + zero_shift_rad[i] * kRadToDeg;
    return e;
  }

  // The reply text (without terminator) to one request, or nullopt for no reply (99). Also
  // returns, through wall_delay, how long a paced move takes. Locks the state.
  std::optional<std::string> respond(const irc5::ParsedRequest& r, milliseconds* wall_delay);
  // linear_seconds >= 0: a MoveL of that duration (straight path) instead of a joint move.
  std::string moveTo(const Joints& target, int code, milliseconds* wall_delay,
                     double linear_seconds = -1);
  // Charges a move's time to the clock (and, paced, to the reply's wall delay).
  void charge(const irc5::MoveTime& t, milliseconds* wall_delay);
  // The robot at rest at `stored`: a new repeatability draw and the gross-error state.
  void arrive(const Joints& stored);
  // Request 49 (after the three rows of 47): the reply text.
  std::string searchRun(const SearchRun& run, milliseconds* wall_delay);
  Frame<double> toolInWobj(const Joints& q) const;
  bool solveIk(const Frame<double>& flange_target, Joints* q) const;

  SimControllerOptions options;
  asio::io_context ctx;
  tcp::acceptor acceptor;
  tcp::endpoint endpoint;                 // where it listens
  asio::steady_timer restart_timer{ctx};  // the end of a restart (I/O thread)
  bool stopped = false;                   // I/O thread
  std::thread thread;
  std::set<std::shared_ptr<Session>> sessions;  // I/O thread only

  mutable std::mutex mutex;  // guards everything below
  // Where the true beam meets the PSD now, as the detector sees it (stray light included).
  std::optional<BeamHit> spotNow() const;

  std::mt19937_64 rng;
  std::mt19937_64 gross_rng;   // its own stream: the repeatability draws stay those of the seed
  std::mt19937_64 search_rng;  // the search signal's latency, its own stream for the same reason
  SpotSearch search;           // the spiral given by 47
  int search_rows = 0;         // bit r: row r of 47 received
  SimFaults faults;
  Joints commanded{};
  Joints move_error{};  // this move's repeatability error plus an unsettled reading's
  GrossState gross;
  Frame<double> tool, wobj;
  double speed_tcp_mm_s = 100, speed_ori_deg_s = 50;
  bool fine = false;
  double sim_time_s = 0;
  MotionTotals totals;
  long requests = 0, connections = 0, restarts = 0;
  std::array<double, kJointCount> cal_offset{}, transmission{}, zero_shift_rad{};
  // Written over the link (45), taken at the next restart (46).
  std::array<std::optional<double>, kJointCount> pending_cal{};
  bool restart_requested = false;
  // Moves joint i's zero for a new cal_offset: q = (phi - cal) / k with the revolution
  // counter's turn unchanged, so theta - q grows by the change over k. Locked by the caller.
  void takeCalOffset(int i, double stored) {
    zero_shift_rad[i] += (stored - cal_offset[i]) / transmission[i];
    cal_offset[i] = stored;
  }
  // The restart after 46 has been answered: pending values taken, every connection dropped,
  // restart_s charged to the simulated clock; when paced, the listener closed for pace x
  // restart_s of wall time (connections refused), as a restarting controller's. I/O thread.
  void restart();
  // Listens again at the end of a restart. I/O thread.
  void relisten();
};

void SimController::Impl::initMotorCalibration() {
  transmission = options.motor.transmission.value_or(options.world.robot.transmission);
  if (options.motor.cal_offset_rad) {
    cal_offset = *options.motor.cal_offset_rad;
  } else {
    // Every public controller backup holds cal_offset in [0, 2 pi) (docs/apply.md).
    std::mt19937_64 fixed(options.seed ^ 0x5eed);
    std::uniform_real_distribution<double> u(0.0, 2 * kPi);
    for (double& v : cal_offset) v = u(fixed);
  }
  std::vector<std::string> problems;
  for (int i = 0; i < kJointCount; ++i) {
    cal_offset[i] = f32(cal_offset[i]);
    if (!(cal_offset[i] >= 0 && cal_offset[i] < 2 * kPi))
      problems.push_back("motor.cal_offset_rad of joint " + std::to_string(i + 1) +
                         " is outside [0, 2 pi)");
  }
  if (!problems.empty()) throw ConfigError("SimControllerOptions", problems);
}

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
  milliseconds down(0);
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (!restart_requested) return;
    restart_requested = false;
    search_rows = 0;  // the RAPID program starts over
    for (int i = 0; i < kJointCount; ++i)
      if (pending_cal[i]) takeCalOffset(i, *pending_cal[i]);
    pending_cal.fill(std::nullopt);
    sim_time_s += options.restart_s;
    ++restarts;
    if (options.pace > 0)
      down = milliseconds(static_cast<long long>(options.restart_s * options.pace * 1000));
  }
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

Frame<double> SimController::Impl::toolInWobj(const Joints& q) const {
  return inverse(wobj) * (flangePoseDeg(options.world.robot, q) * tool);
}

// Damped Newton on the flange pose from the current joints: the simulator only needs the
// nearby solution a MoveL would reach, not every branch of the analytic inverse.
bool SimController::Impl::solveIk(const Frame<double>& target, Joints* q) const {
  const Robot& robot = options.world.robot;
  const auto error = [&](const Joints& x) {
    const Frame<double> f = flangePoseDeg(robot, x);
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() = target.p - f.p;
    const Eigen::AngleAxisd aa(target.R * f.R.transpose());
    e.tail<3>() = aa.angle() * aa.axis() * 1000.0;  // weight: 1 rad ~ 1000 mm
    return e;
  };
  Joints x = *q;
  for (int iter = 0; iter < 100; ++iter) {
    const Eigen::Matrix<double, 6, 1> e = error(x);
    if (e.head<3>().norm() < 1e-7 && e.tail<3>().norm() < 1e-7) {
      *q = x;
      return robot.withinLimits(x);
    }
    Eigen::Matrix<double, 6, 6> jac;
    constexpr double h = 1e-6;  // deg
    for (int j = 0; j < kJointCount; ++j) {
      Joints xp = x;
      xp[j] += h;
      jac.col(j) = (e - error(xp)) / h;
    }
    const Eigen::Matrix<double, 6, 1> step =
        (jac.transpose() * jac + 1e-9 * Eigen::Matrix<double, 6, 6>::Identity())
            .ldlt()
            .solve(jac.transpose() * e);
    const double scale = std::min(1.0, 10.0 / step.cwiseAbs().maxCoeff());  // at most 10 deg
    for (int j = 0; j < kJointCount; ++j) x[j] += scale * step[j];
  }
  return false;
}

std::string SimController::Impl::moveTo(const Joints& target, int code, milliseconds* wall_delay,
                                        double linear_seconds) {
  Joints stored;
  for (int i = 0; i < kJointCount; ++i) stored[i] = f32(target[i]);
  const std::string violation = options.world.robot.limitViolation(stored);
  if (!violation.empty()) return std::to_string(code) + " 0 out of bounds";
  irc5::MoveTime t;
  if (linear_seconds >= 0) {
    double largest = 0;
    for (int i = 0; i < kJointCount; ++i)
      largest = std::max(largest, std::abs(stored[i] - commanded[i]));
    t.motion_s = irc5::rampedSeconds(linear_seconds, largest, options.motion.joint_accel_deg_s2);
    t.overhead_s = options.motion.overhead_s;
    t.settle_s = options.motion.settle_s;
  } else {
    t = irc5::jointMoveTime(options.world.robot, commanded, stored, speed_tcp_mm_s, speed_ori_deg_s,
                            options.motion);
  }
  charge(t, wall_delay);
  arrive(stored);
  return std::to_string(code) + " 1 ";
}

void SimController::Impl::charge(const irc5::MoveTime& t, milliseconds* wall_delay) {
  const double seconds = t.total();
  sim_time_s += seconds;
  ++totals.moves;
  totals.motion_s += t.motion_s;
  totals.overhead_s += t.overhead_s;
  totals.settle_s += t.settle_s;
  if (options.pace > 0)
    *wall_delay = milliseconds(static_cast<long long>(seconds * options.pace * 1000));
}

void SimController::Impl::arrive(const Joints& stored) {
  commanded = stored;
  std::normal_distribution<double> noise(0.0, options.world.noise.repeatability_deg);
  for (double& e : move_error) e = options.world.noise.repeatability_deg > 0 ? noise(rng) : 0.0;
  updateGross(options.world.gross, commanded, gross_rng, &gross);
  for (int i = 0; i < kJointCount; ++i) move_error[i] += gross.unsettled_deg[i];
}

std::string SimController::Impl::searchRun(const SearchRun& run, milliseconds* wall_delay) {
  const std::string c = std::to_string(irc5::kSearchRun);
  const Robot& robot = options.world.robot;
  // The waypoints as the module computes them (RAPID nums), each checked before anything moves.
  constexpr std::size_t kMaxWaypoints = 5000;
  std::vector<Joints> path{commanded};
  forEachSearchWaypoint(search, run, [&](const Joints& q) {
    Joints stored;
    for (int i = 0; i < kJointCount; ++i) stored[i] = f32(q[i]);
    path.push_back(stored);
    return path.size() <= kMaxWaypoints;
  });
  if (path.size() < 2 || path.size() > kMaxWaypoints) return c + " 0 bad run";
  for (const Joints& q : path)
    if (!robot.limitViolation(q).empty()) return c + " 0 out of bounds";
  // Time along the path: each joint segment at the run's speed, one ramp up and down for all.
  std::vector<double> until{0.0};  // cruise seconds at each waypoint
  double largest = 0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    until.push_back(until.back() + irc5::jointMoveSeconds(robot, path[i - 1], path[i],
                                                          run.speed_mm_s, speed_ori_deg_s));
    for (int j = 0; j < kJointCount; ++j)
      largest = std::max(largest, std::abs(path[i][j] - path[0][j]));
  }
  const double cruise = until.back();
  const double motion_s = irc5::rampedSeconds(cruise, largest, options.motion.joint_accel_deg_s2);
  const double scale = cruise > 0 ? motion_s / cruise : 1.0;
  irc5::MoveTime t;
  t.overhead_s = options.motion.overhead_s;
  t.settle_s = options.motion.settle_s;
  const double t0 = sim_time_s + t.overhead_s;
  const sim::PsdModel detector(options.search.psd);
  const auto lit = [&](const Joints& q, double at) {
    const std::optional<BeamHit> hit = beamHit(options.world, q, trueExtraDeg(), at);
    return hit && detector.ideal(hit->spot).sum > options.search.threshold_v;
  };
  const auto along = [&](std::size_t i, double f) {  // segment i (to waypoint i), fraction f
    Joints q;
    for (int j = 0; j < kJointCount; ++j) q[j] = path[i - 1][j] + f * (path[i][j] - path[i - 1][j]);
    return q;
  };
  // The input interrupts on a rising edge only (ISignalDI \Single): light already on the
  // detector at the start raises nothing until it has gone and come back.
  bool was_lit = lit(path[0], t0);
  std::size_t rose_in = 0;
  double rose_s = 0;
  for (std::size_t i = 1; i < path.size() && rose_in == 0; ++i) {
    double largest_step = 0;
    for (int j = 0; j < kJointCount; ++j)
      largest_step = std::max(largest_step, std::abs(path[i][j] - path[i - 1][j]));
    // 0.005 deg moves the spot ~0.1 mm at a metre: far finer than the 5.7 mm lit disk.
    const int n = std::max(1, static_cast<int>(std::ceil(largest_step / 0.005)));
    for (int k = 1; k <= n; ++k) {
      const double f = static_cast<double>(k) / n;
      const double at = until[i - 1] + f * (until[i] - until[i - 1]);
      const bool now_lit = lit(along(i, f), t0 + at * scale);
      if (now_lit && !was_lit) {
        rose_in = i;
        rose_s = at;
        break;
      }
      was_lit = now_lit;
    }
  }
  std::size_t stop_at = path.size() - 1;
  std::optional<Joints> latched;
  if (rose_in > 0) {
    std::uniform_real_distribution<double> latency(options.search.latency_min_s,
                                                   options.search.latency_max_s);
    const double latch_s = std::min(cruise, rose_s + latency(search_rng));
    std::size_t i = rose_in;
    while (i + 1 < path.size() && until[i] < latch_s) ++i;
    const double span = until[i] - until[i - 1];
    const Joints q =
        along(i, span > 0 ? std::clamp((latch_s - until[i - 1]) / span, 0.0, 1.0) : 1.0);
    latched.emplace();
    for (int j = 0; j < kJointCount; ++j) (*latched)[j] = f32(q[j]);
    // The module stops queueing waypoints once the trap has run; the one queued for the zone
    // (the program pointer runs a move ahead) is still driven to.
    stop_at = std::min(path.size() - 1, i + 1);
  }
  t.motion_s = motion_s * (cruise > 0 ? until[stop_at] / cruise : 1.0);
  charge(t, wall_delay);
  ++totals.search_moves;
  arrive(path[stop_at]);
  if (!latched) return c + " 1 0";
  std::string reply = c + " 1 1";
  for (double v : *latched) reply += " " + fmt(v, irc5::kJointDecimals);
  return reply;
}

std::optional<BeamHit> SimController::Impl::spotNow() const {
  std::optional<BeamHit> hit = beamHit(options.world, commanded, trueExtraDeg(), sim_time_s);
  if (hit) {
    hit->spot.u_mm += gross.stray_light_mm.x();
    hit->spot.v_mm += gross.stray_light_mm.y();
  }
  return hit;
}

std::optional<std::string> SimController::Impl::respond(const irc5::ParsedRequest& r,
                                                        milliseconds* wall_delay) {
  std::lock_guard<std::mutex> lock(mutex);
  const std::string c = std::to_string(r.code);
  const std::string bad = c + " 0 ";
  const std::string done = c + " 1 ";
  if (!r.valid) return std::string("0 0 ");
  const std::size_t n = r.params.size();
  const auto six = [&](const std::array<double, 6>& v, int decimals) {
    std::string s = done;
    for (int i = 0; i < 6; ++i) s += fmt(v[i], decimals) + (i < 5 ? " " : "");
    return s;
  };
  switch (r.code) {
    case irc5::kPing:
      return n == 0 ? done : bad;
    case irc5::kMoveLinear: {
      if (n != 7) return bad;
      std::vector<double> p;
      for (double v : r.params) p.push_back(f32(v));
      const Frame<double> flange = wobj * frameOf(p) * inverse(tool);
      Joints q = commanded;
      if (!solveIk(flange, &q)) return c + " 0 unreachable";
      const Frame<double> from = toolInWobj(commanded);
      const double dist = (from.p - Eigen::Vector3d(p[0], p[1], p[2])).norm();
      const double angle = Eigen::AngleAxisd(from.R.transpose() * frameOf(p).R).angle();
      const double linear = std::max(dist / speed_tcp_mm_s, angle * kRadToDeg / speed_ori_deg_s);
      const std::string reply = moveTo(q, r.code, wall_delay, linear);
      return reply;
    }
    case irc5::kMoveJoints: {
      if (n != 6) return bad;
      Joints q;
      std::copy(r.params.begin(), r.params.end(), q.begin());
      return moveTo(q, r.code, wall_delay);
    }
    case irc5::kReadPose: {
      if (n != 0) return bad;
      const Frame<double> f = toolInWobj(commanded);
      Eigen::Quaterniond q(f.R);
      if (q.w() < 0) q.coeffs() *= -1;
      std::string s = done;
      for (int i = 0; i < 3; ++i) s += fmt(f32(f.p[i]), irc5::kXyzDecimals) + " ";
      const double qs[4] = {q.w(), q.x(), q.y(), q.z()};
      for (int i = 0; i < 4; ++i) s += fmt(f32(qs[i]), irc5::kQuatDecimals) + (i < 3 ? " " : "");
      return s;
    }
    case irc5::kReadJoints:
      return n == 0 ? six(commanded, irc5::kJointDecimals) : bad;
    case irc5::kReadExternalAxes:
      // No external axes: RAPID reports 9E9 for unused ones.
      return n == 0 ? done + "9E+09 9E+09 9E+09 9E+09 9E+09 9E+09" : bad;
    case irc5::kSetTool:
    case irc5::kSetWorkObject: {
      if (n != 7) return bad;
      std::vector<double> p;
      for (double v : r.params) p.push_back(f32(v));
      (r.code == irc5::kSetTool ? tool : wobj) = frameOf(p);
      return done;
    }
    case irc5::kSetSpeed:
      if (n != 4 && n != 2) return bad;
      if (!(r.params[0] > 0) || !(r.params[1] > 0)) return c + " 0 speeds must be positive";
      speed_tcp_mm_s = f32(r.params[0]);
      speed_ori_deg_s = f32(r.params[1]);
      return done;
    case irc5::kSetZone:
      if (n != 4) return bad;
      fine = r.params[0] == 1;
      return done;
    case irc5::kStop:
      return n == 0 ? done : bad;  // a move has ended (simulated) before its reply
    case irc5::kReadCalOffset: {
      // The configuration's values, written ones included, as ReadCfgData reads them.
      if (n != 0) return bad;
      std::array<double, 6> configured = cal_offset;
      for (int i = 0; i < kJointCount; ++i) configured[i] = pending_cal[i].value_or(cal_offset[i]);
      return six(configured, 6);
    }
    case irc5::kWriteCalOffset: {
      if (n != 2) return bad;
      const double joint = r.params[0], value = f32(r.params[1]);
      if (!(joint >= 1 && joint <= kJointCount && joint == std::floor(joint)) ||
          !(value >= 0 && value < 2 * kPi))
        return bad;
      const int i = static_cast<int>(joint) - 1;
      if (transmission[i] == 0) return c + " 0 transmission unknown";
      pending_cal[i] = value;
      return done;
    }
    case irc5::kRestart:
      if (n != 0) return bad;
      restart_requested = true;
      return done;
    case irc5::kReadMotorAngles: {
      // ReadMotor: the motor's angle behind the joint angle the controller reports, q = (phi -
      // cal_offset) / k with the arm's true k, within one motor turn (docs/apply.md: inferred).
      if (n != 0) return bad;
      std::array<double, 6> phi;
      for (int i = 0; i < kJointCount; ++i) {
        const double turns = cal_offset[i] + transmission[i] * commanded[i] * kDegToRad;
        phi[i] = f32(turns - 2 * kPi * std::floor(turns / (2 * kPi)));
      }
      return six(phi, 6);
    }
    case irc5::kReadJointBounds: {
      if (n != 1 || (r.params[0] != 0 && r.params[0] != 1)) return bad;
      std::array<double, 6> b;
      for (int i = 0; i < 6; ++i) {
        const JointLimit& l = options.world.robot.limits[i];
        b[i] = r.params[0] == 0 ? l.lower_deg : l.upper_deg;
      }
      return six(b, 3);
    }
    case irc5::kSearchSpiral: {
      // Row 0: the centre's joints; rows 1 and 2: the joints per mm of spot along u and v.
      if (n != 7 || !(r.params[0] == 0 || r.params[0] == 1 || r.params[0] == 2)) return bad;
      if (!options.search.wired) return c + " 0 no search signal";
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
          !(run.speed_mm_s > 0) || run.speed_mm_s > speed_tcp_mm_s)
        return bad;
      search.pitch_mm = pitch;
      return searchRun(run, wall_delay);
    }
    case irc5::kSimBeamSpot: {
      // Simulator only: what a PSD placed in the world would see now (an external daemon's
      // simulated board asks this over its own connection).
      if (n != 0) return bad;
      const std::optional<BeamHit> hit = spotNow();
      if (!hit || !hit->spot.finite() || std::abs(hit->spot.u_mm) > 1e6 ||
          std::abs(hit->spot.v_mm) > 1e6)
        return done + "0 0 0";
      return done + "1 " + fmt(hit->spot.u_mm, 5) + " " + fmt(hit->spot.v_mm, 5);
    }
    case irc5::kSimWorldId:
      return n == 0 ? done + worldHash(options.world) + " " + std::to_string(options.seed) : bad;
    case irc5::kRobotInfo:
      return n == 0
                 ? done + options.serial + "*" + options.software_version + "*" + options.robot_type
                 : bad;
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

Joints SimController::commandedJoints() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->commanded;
}

Joints SimController::moveErrorDeg() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->move_error;
}

std::optional<BeamHit> SimController::beamHitNow() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->spotNow();
}

std::array<double, kJointCount> SimController::calOffsets() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->cal_offset;
}

void SimController::writeCalOffset(int joint, double rad) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const std::string where = "joint " + std::to_string(joint);
  if (joint < 1 || joint > kJointCount) throw ConfigError("simulated controller", {"no " + where});
  const int i = joint - 1;
  const double stored = f32(rad);
  if (!(stored >= 0 && stored < 2 * kPi))
    throw ConfigError("simulated controller", {where + ": cal_offset outside [0, 2 pi)"});
  if (impl_->transmission[i] == 0)
    throw ConfigError("simulated controller", {where + ": the arm's transmission is unknown"});
  impl_->takeCalOffset(i, stored);
  impl_->pending_cal[i].reset();
}

void SimController::updateRevolutionCounter(int joint) {
  if (joint < 1 || joint > kJointCount)
    throw ConfigError("simulated controller", {"no joint " + std::to_string(joint)});
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const int i = joint - 1;
  const double k = impl_->transmission[i];
  if (k == 0) return;
  // At the mark the joint reads -shift; the counter takes the turn that brings the reading
  // within half a motor turn of the calibration position.
  const double turn = 2 * kPi / k;
  impl_->zero_shift_rad[i] -= turn * std::round(impl_->zero_shift_rad[i] / turn);
}

Joints SimController::zeroShiftDeg() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Joints d;
  for (int i = 0; i < kJointCount; ++i) d[i] = impl_->zero_shift_rad[i] * kRadToDeg;
  return d;
}

double SimController::simTimeS() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->sim_time_s;
}

MotionTotals SimController::motionTotals() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->totals;
}

long SimController::restartCount() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->restarts;
}

long SimController::requestCount() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->requests;
}

long SimController::connectionCount() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->connections;
}

void SimController::placePsd(int placement,
                             const std::vector<Eigen::Vector3d>& planned_centres_mm) {
  if (placement < 1 || placement > static_cast<int>(planned_centres_mm.size()))
    throw ConfigError("simulated controller", {"no PSD placement " + std::to_string(placement) +
                                               " of " + std::to_string(planned_centres_mm.size())});
  std::lock_guard<std::mutex> lock(impl_->mutex);
  World& w = impl_->options.world;
  // Every placement of the session, drawn anew from the seed: the same truth whichever
  // placement a run (re)starts at.
  w.placements.clear();
  for (std::size_t p = 1; p < planned_centres_mm.size(); ++p)
    w.placements.push_back(
        drawPlacement(w, impl_->options.seed, static_cast<int>(p + 1), planned_centres_mm[p]));
  w.active_placement = placement;
}

const World& SimController::world() const { return impl_->options.world; }

}  // namespace zerocal
