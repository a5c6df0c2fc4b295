#include "zerocal/sim/simulated_arm.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <mutex>
#include <random>

#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"

namespace zerocal::sim {

namespace {

constexpr const char* kOrigin = "simulated arm";

Frame<double> frameOf(const TcpPose& pose) {
  Frame<double> f;
  f.p = Eigen::Vector3d(pose.xyz_mm[0], pose.xyz_mm[1], pose.xyz_mm[2]);
  const auto& w = pose.quat_wxyz;
  Eigen::Quaterniond q(w[0], w[1], w[2], w[3]);
  if (q.norm() < 1e-9) q = Eigen::Quaterniond::Identity();
  f.R = q.normalized().toRotationMatrix();
  return f;
}

Frame<double> inverse(const Frame<double>& f) { return {f.R.transpose(), -f.R.transpose() * f.p}; }

MoveResult refused(MoveRefusal why) {
  MoveResult r;
  r.refusal = why;
  return r;
}

}  // namespace

double roundToFloat32(double v) {
  // The volatile store keeps the rounding: with a plain cast, GCC 12 at -O3 vectorised a loop of
  // six of these and left the last two joints unrounded (caught by the float32 read-back test).
  volatile float f = static_cast<float>(v);
  return static_cast<double>(f);
}

std::string MotionModel::validate() const {
  if (!cruise_s || !profile_s) return "a cruise time and a speed profile are needed";
  if (!(overhead_s >= 0) || !(settle_s >= 0)) return "overhead_s and settle_s must be >= 0";
  return {};
}

std::uint64_t grossSeed(std::uint64_t seed) { return seed ^ 0x67726f7373ull; }
std::uint64_t searchSeed(std::uint64_t seed) { return seed ^ 0x736561726368ull; }
std::uint64_t seatSeed(std::uint64_t seed) { return seed ^ 0x73656174ull; }

struct SimulatedArm::State {
  explicit State(SimulatedArmOptions o)
      : options(std::move(o)),
        rng(options.seed),
        gross_rng(grossSeed(options.seed)),
        search_rng(searchSeed(options.seed)) {
    const std::string motion = options.motion.validate();
    if (!motion.empty()) throw ConfigError(kOrigin, {"motion: " + motion});
    if (!(options.restart_s >= 0 && options.restart_s <= 3600))
      throw ConfigError(kOrigin, {"restart_s must be within 0..3600 s"});
    if (!(options.warm_s >= 0 && options.warm_s <= kMaxWarmS))
      throw ConfigError(kOrigin, {"warm_s must be within 0.." +
                                  std::to_string(static_cast<long>(kMaxWarmS)) + " s (a week)"});
    time_s = options.warm_s;
    seatPsd(options.seed);
    commanded = store(options.start_joints);
    initMotorCalibration();
    const std::string violation = options.world.robot.limitViolation(commanded);
    if (!violation.empty()) throw ConfigError(kOrigin, {"start joints: " + violation});
  }

  double store(double v) const { return options.single_precision ? roundToFloat32(v) : v; }
  Joints store(const Joints& q) const {
    Joints s;
    for (int i = 0; i < kJointCount; ++i) s[i] = store(q[i]);
    return s;
  }

  // Where the session whose draws start from `seed` finds the PSD seated on its base
  // (World::psd_seated_mm): its own stream, so that the other draws stay what they were.
  void seatPsd(std::uint64_t seed) {
    Eigen::Vector3d& seated = options.world.psd_seated_mm;
    seated.setZero();
    const double sigma = options.world.noise.psd_seat_mm;
    if (!(sigma > 0)) return;
    std::mt19937_64 rng(seatSeed(seed));
    std::normal_distribution<double> normal(0.0, sigma);
    for (int i = 0; i < 3; ++i) seated[i] = normal(rng);
  }

  void initMotorCalibration() {
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
      cal_offset[i] = store(cal_offset[i]);
      if (!(cal_offset[i] >= 0 && cal_offset[i] < 2 * kPi))
        problems.push_back("motor.cal_offset_rad of joint " + std::to_string(i + 1) +
                           " is outside [0, 2 pi)");
    }
    if (!problems.empty()) throw ConfigError(kOrigin, problems);
  }

  // The true joint angles' excess over commanded + world offsets: the move's error plus how far
  // cal_offset changes have moved each zero (deg).
  Joints trueExtraDeg() const {
    Joints e;
    for (int i = 0; i < kJointCount; ++i) e[i] = move_error[i] + zero_shift_rad[i] * kRadToDeg;
    return e;
  }

  std::optional<BeamHit> spotNow() const {
    std::optional<BeamHit> hit = beamHit(options.world, commanded, trueExtraDeg(), time_s);
    if (hit) {
      hit->spot.u_mm += gross.stray_light_mm.x();
      hit->spot.v_mm += gross.stray_light_mm.y();
    }
    return hit;
  }

  Frame<double> toolInWobj(const Joints& q) const {
    return inverse(wobj) * (flangePoseDeg(options.world.robot, q) * tool);
  }

  CalOffsetRefusal checkCalOffset(int joint, double stored) const {
    if (joint < 1 || joint > kJointCount) return CalOffsetRefusal::kNoSuchJoint;
    if (!(stored >= 0 && stored < 2 * kPi)) return CalOffsetRefusal::kOutOfRange;
    if (transmission[joint - 1] == 0) return CalOffsetRefusal::kTransmissionUnknown;
    return CalOffsetRefusal::kNone;
  }

  // Moves joint i's zero for a new cal_offset: q = (phi - cal) / k with the revolution
  // counter's turn unchanged, so theta - q grows by the change over k.
  void takeCalOffset(int i, double stored) {
    zero_shift_rad[i] += (stored - cal_offset[i]) / transmission[i];
    cal_offset[i] = stored;
  }

  bool solveIk(const Frame<double>& flange_target, Joints* q) const;
  // linear_cruise_s >= 0: a linear move of that cruise time instead of a joint move.
  MoveResult moveTo(const Joints& target, double linear_cruise_s);
  MoveResult search(const SpotSearch& spiral, const SearchRun& run);
  void charge(const MoveCost& cost);
  // The arm at rest at `stored`: a new repeatability draw and the gross-error state.
  void arrive(const Joints& stored);

  SimulatedArmOptions options;
  mutable std::mutex mutex;  // guards everything (options.world's placements included)
  std::mt19937_64 rng;
  std::mt19937_64 gross_rng;   // its own stream: the repeatability draws stay those of the seed
  std::mt19937_64 search_rng;  // the search signal's latency, its own stream for the same reason
  std::uint64_t noise_seed = options.seed;  // what the three streams above were last seeded from
  Joints commanded{};
  Joints move_error{};  // this move's repeatability error plus an unsettled reading's
  GrossState gross;
  Frame<double> tool, wobj;
  MoveSpeed speed;
  double time_s = 0;
  MotionTotals totals;
  long restarts = 0;
  std::array<double, kJointCount> cal_offset{}, transmission{}, zero_shift_rad{};
  // Written into the configuration, taken at the next restart.
  std::array<std::optional<double>, kJointCount> pending_cal{};
};

// Damped Newton on the flange pose from the current joints: the simulator only needs the
// nearby solution a MoveL would reach, not every branch of the analytic inverse.
bool SimulatedArm::State::solveIk(const Frame<double>& target, Joints* q) const {
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

MoveResult SimulatedArm::State::moveTo(const Joints& target, double linear_cruise_s) {
  const Joints stored = store(target);
  if (!options.world.robot.limitViolation(stored).empty())
    return refused(MoveRefusal::kOutOfLimits);
  double largest = 0;
  for (int i = 0; i < kJointCount; ++i)
    largest = std::max(largest, std::abs(stored[i] - commanded[i]));
  const double cruise_s =
      linear_cruise_s >= 0 ? linear_cruise_s
                           : options.motion.cruise_s(options.world.robot, commanded, stored, speed);
  MoveResult result;
  result.cost.motion_s = options.motion.profile_s(cruise_s, largest);
  result.cost.overhead_s = options.motion.overhead_s;
  result.cost.settle_s = options.motion.settle_s;
  charge(result.cost);
  arrive(stored);
  return result;
}

void SimulatedArm::State::charge(const MoveCost& cost) {
  time_s += cost.total();
  ++totals.moves;
  totals.motion_s += cost.motion_s;
  totals.overhead_s += cost.overhead_s;
  totals.settle_s += cost.settle_s;
}

void SimulatedArm::State::arrive(const Joints& stored) {
  commanded = stored;
  std::normal_distribution<double> noise(0.0, options.world.noise.repeatability_deg);
  for (double& e : move_error) e = options.world.noise.repeatability_deg > 0 ? noise(rng) : 0.0;
  updateGross(options.world.gross, commanded, gross_rng, &gross);
  for (int i = 0; i < kJointCount; ++i) move_error[i] += gross.unsettled_deg[i];
}

MoveResult SimulatedArm::State::search(const SpotSearch& spiral, const SearchRun& run) {
  if (!options.search.wired) return refused(MoveRefusal::kNoSearchSignal);
  const Robot& robot = options.world.robot;
  // The waypoints as the controller stores them, each checked before anything moves.
  constexpr std::size_t kMaxWaypoints = 5000;  // the start included
  std::vector<Joints> path{commanded};
  forEachSearchWaypoint(spiral, run, [&](const Joints& q) {
    path.push_back(store(q));
    return path.size() <= kMaxWaypoints;
  });
  if (path.size() < 2 || path.size() > kMaxWaypoints) return refused(MoveRefusal::kBadPath);
  for (const Joints& q : path)
    if (!robot.limitViolation(q).empty()) return refused(MoveRefusal::kOutOfLimits);
  // Time along the path: each joint segment at the run's speed, one ramp up and down for all.
  const MoveSpeed run_speed{run.speed_mm_s, speed.ori_deg_s};
  std::vector<double> until{0.0};  // cruise seconds at each waypoint
  double largest = 0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    until.push_back(until.back() + options.motion.cruise_s(robot, path[i - 1], path[i], run_speed));
    for (int j = 0; j < kJointCount; ++j)
      largest = std::max(largest, std::abs(path[i][j] - path[0][j]));
  }
  const double cruise = until.back();
  const double motion_s = options.motion.profile_s(cruise, largest);
  const double scale = cruise > 0 ? motion_s / cruise : 1.0;
  MoveResult result;
  result.cost.overhead_s = options.motion.overhead_s;
  result.cost.settle_s = options.motion.settle_s;
  const double t0 = time_s + result.cost.overhead_s;
  const PsdModel detector(options.search.psd);
  const auto lit = [&](const Joints& q, double at) {
    const std::optional<BeamHit> hit = beamHit(options.world, q, trueExtraDeg(), at);
    return hit && detector.ideal(hit->spot).sum > options.search.threshold_v;
  };
  const auto along = [&](std::size_t i, double f) {  // segment i (to waypoint i), fraction f
    Joints q;
    for (int j = 0; j < kJointCount; ++j) q[j] = path[i - 1][j] + f * (path[i][j] - path[i - 1][j]);
    return q;
  };
  // The input interrupts on a rising edge only: light already on the detector at the start
  // raises nothing until it has gone and come back.
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
  if (rose_in > 0) {
    std::uniform_real_distribution<double> latency(options.search.latency_min_s,
                                                   options.search.latency_max_s);
    const double latch_s = std::min(cruise, rose_s + latency(search_rng));
    std::size_t i = rose_in;
    while (i + 1 < path.size() && until[i] < latch_s) ++i;
    const double span = until[i] - until[i - 1];
    result.latched_deg =
        store(along(i, span > 0 ? std::clamp((latch_s - until[i - 1]) / span, 0.0, 1.0) : 1.0));
    // The controller stops queueing waypoints once the latch has run; the one queued for the
    // zone (the program pointer runs a move ahead) is still driven to.
    stop_at = std::min(path.size() - 1, i + 1);
  }
  result.cost.motion_s = motion_s * (cruise > 0 ? until[stop_at] / cruise : 1.0);
  charge(result.cost);
  ++totals.search_moves;
  arrive(path[stop_at]);
  return result;
}

SimulatedArm::SimulatedArm(SimulatedArmOptions options)
    : state_(std::make_unique<State>(std::move(options))) {}

SimulatedArm::~SimulatedArm() = default;

MoveResult SimulatedArm::moveJoints(const Joints& target_deg) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->moveTo(target_deg, -1);
}

MoveResult SimulatedArm::moveLinear(const TcpPose& target) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  State& s = *state_;
  const Frame<double> goal = frameOf(target);
  Joints q = s.commanded;
  if (!s.solveIk(s.wobj * goal * inverse(s.tool), &q)) return refused(MoveRefusal::kUnreachable);
  const Frame<double> from = s.toolInWobj(s.commanded);
  const double dist = (from.p - goal.p).norm();
  const double angle = Eigen::AngleAxisd(from.R.transpose() * goal.R).angle();
  return s.moveTo(q, std::max(dist / s.speed.tcp_mm_s, angle * kRadToDeg / s.speed.ori_deg_s));
}

MoveResult SimulatedArm::searchRun(const SpotSearch& spiral, const SearchRun& run) {
  assert(spiral.pitch_mm > 0 && run.from_mm >= 0 && run.to_mm >= run.from_mm && run.speed_mm_s > 0);
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->search(spiral, run);
}

void SimulatedArm::setTool(const TcpPose& tool_in_flange) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  state_->tool = frameOf(tool_in_flange);
}

void SimulatedArm::setWorkObject(const TcpPose& wobj_in_base) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  state_->wobj = frameOf(wobj_in_base);
}

void SimulatedArm::setSpeed(const MoveSpeed& speed) {
  assert(speed.tcp_mm_s > 0 && speed.ori_deg_s > 0);
  std::lock_guard<std::mutex> lock(state_->mutex);
  state_->speed = speed;
}

MoveSpeed SimulatedArm::speed() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->speed;
}

Joints SimulatedArm::joints() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->commanded;
}

TcpPose SimulatedArm::toolPose() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const Frame<double> f = state_->toolInWobj(state_->commanded);
  Eigen::Quaterniond q(f.R);
  if (q.w() < 0) q.coeffs() *= -1;
  TcpPose pose;
  pose.xyz_mm = {f.p[0], f.p[1], f.p[2]};
  pose.quat_wxyz = {q.w(), q.x(), q.y(), q.z()};
  return pose;
}

Joints SimulatedArm::moveErrorDeg() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->move_error;
}

std::optional<BeamHit> SimulatedArm::beamHitNow() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->spotNow();
}

bool SimulatedArm::searchSignalWired() const { return state_->options.search.wired; }

double SimulatedArm::timeS() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->time_s;
}

MotionTotals SimulatedArm::motionTotals() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->totals;
}

const RobotInfo& SimulatedArm::identity() const { return state_->options.identity; }

std::uint64_t SimulatedArm::seed() const { return state_->options.seed; }

void SimulatedArm::reseedNoise(std::uint64_t seed) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  state_->rng.seed(seed);
  state_->gross_rng.seed(grossSeed(seed));
  state_->search_rng.seed(searchSeed(seed));
  state_->seatPsd(seed);
  state_->noise_seed = seed;
}

std::uint64_t SimulatedArm::noiseSeed() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->noise_seed;
}

const World& SimulatedArm::world() const { return state_->options.world; }

std::array<double, kJointCount> SimulatedArm::calOffsets() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->cal_offset;
}

std::array<double, kJointCount> SimulatedArm::configuredCalOffsets() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  std::array<double, kJointCount> configured;
  for (int i = 0; i < kJointCount; ++i)
    configured[i] = state_->pending_cal[i].value_or(state_->cal_offset[i]);
  return configured;
}

CalOffsetRefusal SimulatedArm::configureCalOffset(int joint, double rad) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const double stored = state_->store(rad);
  const CalOffsetRefusal refusal = state_->checkCalOffset(joint, stored);
  if (refusal == CalOffsetRefusal::kNone) state_->pending_cal[joint - 1] = stored;
  return refusal;
}

void SimulatedArm::takeCalOffset(int joint, double rad) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const std::string where = "joint " + std::to_string(joint);
  const double stored = state_->store(rad);
  switch (state_->checkCalOffset(joint, stored)) {
    case CalOffsetRefusal::kNone:
      break;
    case CalOffsetRefusal::kNoSuchJoint:
      throw ConfigError(kOrigin, {"no " + where});
    case CalOffsetRefusal::kOutOfRange:
      throw ConfigError(kOrigin, {where + ": cal_offset outside [0, 2 pi)"});
    case CalOffsetRefusal::kTransmissionUnknown:
      throw ConfigError(kOrigin, {where + ": the arm's transmission is unknown"});
  }
  state_->takeCalOffset(joint - 1, stored);
  state_->pending_cal[joint - 1].reset();
}

double SimulatedArm::restart() {
  std::lock_guard<std::mutex> lock(state_->mutex);
  State& s = *state_;
  for (int i = 0; i < kJointCount; ++i)
    if (s.pending_cal[i]) s.takeCalOffset(i, *s.pending_cal[i]);
  s.pending_cal.fill(std::nullopt);
  s.time_s += s.options.restart_s;
  ++s.restarts;
  return s.options.restart_s;
}

long SimulatedArm::restartCount() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->restarts;
}

std::array<double, kJointCount> SimulatedArm::motorAnglesRad() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const State& s = *state_;
  std::array<double, kJointCount> phi;
  for (int i = 0; i < kJointCount; ++i) {
    const double turns = s.cal_offset[i] + s.transmission[i] * s.commanded[i] * kDegToRad;
    phi[i] = turns - 2 * kPi * std::floor(turns / (2 * kPi));
  }
  return phi;
}

void SimulatedArm::updateRevolutionCounter(int joint) {
  if (joint < 1 || joint > kJointCount)
    throw ConfigError(kOrigin, {"no joint " + std::to_string(joint)});
  std::lock_guard<std::mutex> lock(state_->mutex);
  const int i = joint - 1;
  const double k = state_->transmission[i];
  if (k == 0) return;
  // At the mark the joint reads -shift; the counter takes the turn that brings the reading
  // within half a motor turn of the calibration position.
  const double turn = 2 * kPi / k;
  state_->zero_shift_rad[i] -= turn * std::round(state_->zero_shift_rad[i] / turn);
}

Joints SimulatedArm::zeroShiftDeg() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  Joints d;
  for (int i = 0; i < kJointCount; ++i) d[i] = state_->zero_shift_rad[i] * kRadToDeg;
  return d;
}

void SimulatedArm::placePsd(int placement, const std::vector<Eigen::Vector3d>& planned_centres_mm) {
  if (placement < 1 || placement > static_cast<int>(planned_centres_mm.size()))
    throw ConfigError(kOrigin, {"no PSD placement " + std::to_string(placement) + " of " +
                                std::to_string(planned_centres_mm.size())});
  std::lock_guard<std::mutex> lock(state_->mutex);
  World& w = state_->options.world;
  // Every placement of the session, drawn anew from the seed: the same truth whichever
  // placement a run (re)starts at.
  w.placements.clear();
  for (std::size_t p = 1; p < planned_centres_mm.size(); ++p)
    w.placements.push_back(
        drawPlacement(w, state_->options.seed, static_cast<int>(p + 1), planned_centres_mm[p]));
  w.active_placement = placement;
}

}  // namespace zerocal::sim
