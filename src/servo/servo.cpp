#include "zerocal/servo/servo.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <optional>

#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"

namespace zerocal::servo {
namespace {

using JointVector = JointStep;

JointVector toVector(const Joints& q) { return Eigen::Map<const JointVector>(q.data()); }

Eigen::Vector2d toVector(const PsdSpot& spot) { return {spot.u_mm, spot.v_mm}; }

Joints toJoints(const JointVector& v) {
  Joints q;
  for (int i = 0; i < kJointCount; ++i) q[i] = v[i];
  return q;
}

// Where the nominal beam meets the PSD plane, in PSD coordinates. False when it runs parallel.
bool spotOnPlane(const CellModel& cell, const Eigen::Vector3d& centre, const Joints& q,
                 Eigen::Vector2d& uv) {
  const Line line = laserLine(cell, q, CalibrationParameters{});
  const Eigen::Vector3d n = cell.psd_rotation.col(2);
  const double denom = n.dot(line.direction);
  if (std::abs(denom) < 1e-9) return false;
  const double t = n.dot(centre - line.point) / denom;
  const Eigen::Vector3d hit = line.point + t * line.direction;
  uv = (cell.psd_rotation.transpose() * (hit - centre)).head<2>();
  return true;
}

double maxAbs(const JointVector& v) { return v.cwiseAbs().maxCoeff(); }

}  // namespace

ImageJacobian imageJacobian(const CellModel& cell, const Eigen::Vector3d& psd_centre_mm,
                            const Joints& q_deg) {
  // 1e-3 deg moves the spot ~10 um: far above rounding, far below the curvature of the map.
  constexpr double kH = 1e-3;
  ImageJacobian j = ImageJacobian::Zero();
  for (int i = 0; i < kJointCount; ++i) {
    Joints plus = q_deg, minus = q_deg;
    plus[i] += kH;
    minus[i] -= kH;
    Eigen::Vector2d up, um;
    if (spotOnPlane(cell, psd_centre_mm, plus, up) && spotOnPlane(cell, psd_centre_mm, minus, um))
      j.col(i) = (up - um) / (2 * kH);
  }
  return j;
}

std::string ServoOptions::validate() const {
  if (!(tolerance_um > 0)) return "tolerance_um must be positive";
  if (!(hit_zone_mm > 0)) return "hit_zone_mm must be positive";
  if (!(settle_mm > 0)) return "settle_mm must be positive";
  if (!(max_step_deg > 0)) return "max_step_deg must be positive";
  if (!(limit_margin_deg >= 0)) return "limit_margin_deg must not be negative";
  if (!(gain > 0 && gain <= 1)) return "gain must be in (0, 1]";
  if (!(damping_mm >= 0)) return "damping_mm must not be negative";
  if (!(jacobian_prior_mm > 0)) return "jacobian_prior_mm must be positive";
  if (max_iterations < 1) return "max_iterations must be at least 1";
  if (!(timeout_s > 0)) return "timeout_s must be positive";
  if (!(search_step_mm > 0)) return "search_step_mm must be positive";
  if (!(search_radius_mm >= 0)) return "search_radius_mm must not be negative";
  if (max_search_points < 0) return "max_search_points must not be negative";
  if (!(search_time_s > 0)) return "search_time_s must be positive";
  if (!(sweep_speed_mm_s >= 0)) return "sweep_speed_mm_s must not be negative";
  if (!(sweep_pitch_mm > 0)) return "sweep_pitch_mm must be positive";
  if (!(settle_s >= 0)) return "settle_s must not be negative";
  return {};
}

double ServoOptions::recordedWithinMm() const {
  return stop == ServoStop::kZone ? kRecordedWithinZones * hit_zone_mm : 1e-3 * tolerance_um;
}

const char* statusName(ServoStatus status) noexcept {
  switch (status) {
    case ServoStatus::kConverged:
      return "converged";
    case ServoStatus::kSpotNotFound:
      return "spot not found";
    case ServoStatus::kSpotLost:
      return "spot lost";
    case ServoStatus::kNotConverged:
      return "not converged";
    case ServoStatus::kLimit:
      return "limit";
    case ServoStatus::kLinkError:
      return "link error";
    case ServoStatus::kSensorError:
      return "sensor error";
    case ServoStatus::kBadStart:
      return "bad start";
    case ServoStatus::kAborted:
      return "aborted";
  }
  return "?";
}

PsdServo::PsdServo(const CellModel& cell, const Eigen::Vector3d& psd_centre_mm,
                   ServoOptions options)
    : PsdServo(cell, psd_centre_mm, options, default_law_) {}

PsdServo::PsdServo(const CellModel& cell, const Eigen::Vector3d& psd_centre_mm,
                   ServoOptions options, ServoLaw& law)
    : cell_(cell),
      psd_centre_(psd_centre_mm),
      options_(options),
      default_law_(
          {options.gain, options.damping_mm, options.correct_jacobian, options.jacobian_prior_mm}),
      law_(&law) {
  const std::string problem = options_.validate();
  if (!problem.empty()) throw ConfigError("servo options", {problem});
}

void PsdServo::record(const PsdReading& reading) noexcept {
  ServoSample& s = ring_[ring_next_];
  s.time_s = reading.time_s;
  s.q_deg = q_;
  s.reading = reading;
  ring_next_ = (ring_next_ + 1) % kFaultHistory;
  ring_count_ = std::min(ring_count_ + 1, kFaultHistory);
}

ServoResult& PsdServo::latch(ServoResult& result, ServoStatus status,
                             const char* message) noexcept {
  result.status = status;
  result.q_deg = q_;
  faulted_ = true;
  fault_.status = status;
  fault_.message = message;
  fault_.detail[0] = '\0';
  fault_.sample_count = ring_count_;
  const std::size_t first = (ring_next_ + kFaultHistory - ring_count_) % kFaultHistory;
  for (std::size_t i = 0; i < ring_count_; ++i)
    fault_.samples[i] = ring_[(first + i) % kFaultHistory];
  return result;
}

void PsdServo::latchLinkError(ServoResult& result, ServoStatus status,
                              const char* message) noexcept {
  // Called inside a catch handler: the kind is read from the exception in flight, which copies
  // nothing (the servo cycle does not allocate, even on a fault).
  LinkError::Kind kind = LinkError::Kind::kFatal;
  const char* what = "";
  try {
    throw;
  } catch (const LinkError& e) {
    kind = e.kind();
    what = e.what();
  } catch (const std::exception& e) {
    what = e.what();
  } catch (...) {
  }
  latch(result, status, message);
  fault_.link_kind = kind;
  std::strncpy(fault_.detail.data(), what, fault_.detail.size() - 1);
  fault_.detail.back() = '\0';
}

bool PsdServo::aborted(ServoResult& result) noexcept {
  if (options_.abort == nullptr || !options_.abort->load()) return false;
  latch(result, ServoStatus::kAborted, "aborted; the robot at rest where the last move ended");
  return true;
}

PsdServo::Step PsdServo::move(ControllerLink& robot, const Joints& target,
                              ServoResult& result) noexcept {
  if (aborted(result)) return Step::kFailed;
  // Checked here, before anything is sent, whatever computed the target.
  for (int i = 0; i < kJointCount; ++i) {
    if (!(std::abs(target[i] - q_[i]) <= options_.max_step_deg * (1 + 1e-12))) {
      latch(result, ServoStatus::kLimit, "a move would exceed the step limit");
      return Step::kFailed;
    }
  }
  if (!cell_.robot.withinLimits(target, options_.limit_margin_deg)) {
    latch(result, ServoStatus::kLimit, "a move would leave the joint limits less the margin");
    return Step::kFailed;
  }
  try {
    robot.moveJoints(target);
  } catch (...) {
    latchLinkError(result, ServoStatus::kLinkError, "the controller link failed during a move");
    return Step::kFailed;
  }
  q_ = target;
  ++result.moves;
  return Step::kOk;
}

PsdServo::Step PsdServo::walkTo(ControllerLink& robot, const Joints& target,
                                ServoResult& result) noexcept {
  const JointVector from = toVector(q_);
  const JointVector delta = toVector(target) - from;
  const int n = std::max(1, static_cast<int>(std::ceil(maxAbs(delta) / options_.max_step_deg)));
  for (int k = 1; k <= n; ++k) {
    const Joints q = k == n ? target : toJoints(from + delta * (static_cast<double>(k) / n));
    if (move(robot, q, result) != Step::kOk) return Step::kFailed;
  }
  return Step::kOk;
}

PsdServo::Step PsdServo::read(PsdReader& psd, ServoResult& result) noexcept {
  if (aborted(result)) return Step::kFailed;
  try {
    result.reading = psd.read();
  } catch (...) {
    latchLinkError(result, ServoStatus::kSensorError, "the PSD reader failed");
    return Step::kFailed;
  }
  ++result.readings;
  result.end_s = result.reading.time_s;
  record(result.reading);
  if (result.reading.spot_present) keepPathPoint(result.reading, result);
  return Step::kOk;
}

PsdServo::Step PsdServo::settledRead(PsdReader& psd, ServoResult& result) noexcept {
  if (options_.settle_s > 0 && clock_ != nullptr) {
    clock_->waitS(options_.settle_s);
    result.settle_s += options_.settle_s;
  }
  return read(psd, result);
}

void PsdServo::keepPathPoint(const PsdReading& reading, ServoResult& result) noexcept {
  const SpotPathPoint p{reading.time_s - result.start_s, reading.spot};
  if (result.path_count < kPathCapacity) {
    result.path[result.path_count++] = p;
    return;
  }
  // Full: the tail is a ring over path[kPathHead, kPathCapacity), put in order by orderPath().
  result.path[kPathHead + path_tail_next_] = p;
  path_tail_next_ = (path_tail_next_ + 1) % (kPathCapacity - kPathHead);
  ++result.path_skipped;
}

void PsdServo::orderPath(ServoResult& result) const noexcept {
  if (result.path_skipped == 0) return;
  auto tail = result.path.begin() + kPathHead;
  std::rotate(tail, tail + static_cast<std::ptrdiff_t>(path_tail_next_), result.path.end());
}

bool PsdServo::spiral(ControllerLink& robot, PsdReader& psd, const Joints& base_q,
                      const Eigen::Vector2d& expected_uv, double radius_mm, ServoResult& result,
                      bool* failed) noexcept {
  *failed = false;
  const Eigen::Matrix<double, kJointCount, 2> pinv =
      dampedPseudoInverse(imageJacobian(cell_, psd_centre_, base_q), options_.damping_mm);
  const JointVector base = toVector(base_q);
  // Archimedean spiral r = b theta, b = step / 2 pi: turns step apart, points step apart along it.
  const double b = options_.search_step_mm / (2 * kPi);
  // The centre, already read, is not read again.
  const bool centre_new = expected_uv.norm() > 0.5 * options_.search_step_mm;
  double theta = centre_new ? 0.0 : 2 * kPi;
  for (int point = 0; point < options_.max_search_points; ++point) {
    const double r = b * theta;
    if (r > radius_mm) break;
    if (result.reading.time_s - result.start_s > options_.search_time_s) break;
    // Spot offsets wanted from where it is expected: dq = J^+ (wanted - expected).
    const Eigen::Vector2d offset(r * std::cos(theta), r * std::sin(theta));
    const Joints target = toJoints(base + pinv * (offset - expected_uv));
    theta = theta == 0.0 ? 2 * kPi
                         : theta + options_.search_step_mm / std::max(r, options_.search_step_mm);
    // Points the arm cannot reach are skipped; the rest of the spiral may still find the spot.
    if (!cell_.robot.withinLimits(target, options_.limit_margin_deg)) continue;
    const int before = result.moves;
    const Step walked = walkTo(robot, target, result);
    result.search_moves += result.moves - before;
    if (walked != Step::kOk || read(psd, result) != Step::kOk) {
      *failed = true;
      return false;
    }
    if (result.reading.spot_present) {
      // Taken on the fly: the fine servo starts from a settled reading.
      if (options_.settle_s <= 0 || clock_ == nullptr) return true;
      if (settledRead(psd, result) != Step::kOk) {
        *failed = true;
        return false;
      }
      result.settle_acquisition_s = result.settle_s;
      return true;
    }
  }
  return false;
}

PsdServo::Sweep PsdServo::sweep(ControllerLink& robot, PsdReader& psd, const Joints& planned,
                                const PsdSpot& expected, ServoResult& result) noexcept {
  if (!(options_.sweep_speed_mm_s > 0)) return Sweep::kUnavailable;
  // The point-by-point spiral's own mapping, q = planned + J^+ (offset - expected), as rows.
  const Eigen::Matrix<double, kJointCount, 2> pinv =
      dampedPseudoInverse(imageJacobian(cell_, psd_centre_, planned), options_.damping_mm);
  SpotSearch search;
  search.pitch_mm = options_.sweep_pitch_mm;
  search.centre_deg = toJoints(toVector(planned) - pinv * toVector(expected));
  search.per_u_mm = toJoints(pinv.col(0));
  search.per_v_mm = toJoints(pinv.col(1));
  const Sweep first = sweepPass(robot, psd, search, result);
  if (first != Sweep::kNothing) return first;
  // Through the linearised model the turns spread apart far out and may pass either side of
  // the lit disk (seed 14 of the ideal world, 8 mm pitch). The same spiral turned half a turn
  // lays its turns between the first one's.
  search.per_u_mm = toJoints(-pinv.col(0));
  search.per_v_mm = toJoints(-pinv.col(1));
  return sweepPass(robot, psd, search, result);
}

PsdServo::Sweep PsdServo::sweepPass(ControllerLink& robot, PsdReader& psd, const SpotSearch& search,
                                    ServoResult& result) noexcept {
  bool offered = false;
  try {
    offered = robot.startSpotSearch(search);
  } catch (...) {
    latchLinkError(result, ServoStatus::kLinkError, "the controller link failed starting a search");
    return Sweep::kFailed;
  }
  if (!offered) return Sweep::kUnavailable;
  // To the spiral's centre in checked steps, then runs of growing radius, each short enough that
  // an abort waits at most ~kRunS for the move in progress: a run from r0 to r1 is a path of
  // about pi (r1^2 - r0^2) / pitch.
  constexpr double kRunS = 3.0;
  if (maxAbs(toVector(search.centre_deg) - toVector(q_)) > 1e-9) {
    // The signal interrupts on a rising edge: a spiral that starts lit would pass the spot by.
    const int before = result.moves;
    const Step walked = walkTo(robot, search.centre_deg, result);
    result.search_moves += result.moves - before;
    if (walked != Step::kOk || read(psd, result) != Step::kOk) return Sweep::kFailed;
    if (result.reading.spot_present) {
      if (options_.settle_s > 0 && clock_ != nullptr) {
        if (settledRead(psd, result) != Step::kOk) return Sweep::kFailed;
        result.settle_acquisition_s = result.settle_s;
      }
      return result.reading.spot_present ? Sweep::kLit : Sweep::kNear;
    }
  }
  const double area_per_run = options_.sweep_speed_mm_s * kRunS * search.pitch_mm / kPi;
  bool refused = false;
  SearchRun run;
  run.speed_mm_s = options_.sweep_speed_mm_s;
  for (run.from_mm = 0; run.from_mm < options_.search_radius_mm; run.from_mm = run.to_mm) {
    run.to_mm =
        std::min(options_.search_radius_mm, std::sqrt(run.from_mm * run.from_mm + area_per_run));
    if (aborted(result)) return Sweep::kFailed;
    const double now = clock_ != nullptr ? clock_->nowS() : result.end_s;
    if (now - result.start_s > options_.search_time_s) break;
    std::optional<Joints> hit;
    try {
      hit = robot.searchRun(run);
    } catch (const LinkError& e) {
      // A waypoint out of reach (or a run this controller refuses): the spiral point by point
      // skips what it cannot reach.
      if (e.kind() != LinkError::Kind::kRefused) {
        latchLinkError(result, ServoStatus::kLinkError, "the controller link failed in a search");
        return Sweep::kFailed;
      }
      refused = true;
      break;
    } catch (...) {
      latchLinkError(result, ServoStatus::kLinkError, "the controller link failed in a search");
      return Sweep::kFailed;
    }
    ++result.moves;
    ++result.search_moves;
    if (!hit) continue;
    // The robot came to rest a waypoint or so beyond where the light rose: back there.
    if (readBack(robot, result) != Step::kOk) return Sweep::kFailed;
    const int before = result.moves;
    const Step back = walkTo(robot, *hit, result);
    result.search_moves += result.moves - before;
    if (back != Step::kOk || settledRead(psd, result) != Step::kOk) return Sweep::kFailed;
    result.settle_acquisition_s = result.settle_s;
    return result.reading.spot_present ? Sweep::kLit : Sweep::kNear;
  }
  if (readBack(robot, result) != Step::kOk) return Sweep::kFailed;
  return refused ? Sweep::kUnavailable : Sweep::kNothing;
}

PsdServo::Step PsdServo::readBack(ControllerLink& robot, ServoResult& result) noexcept {
  try {
    q_ = robot.readJoints();
  } catch (...) {
    latchLinkError(result, ServoStatus::kLinkError, "the controller link failed reading joints");
    return Step::kFailed;
  }
  return Step::kOk;
}

void PsdServo::notFound(ControllerLink& robot, const Joints& planned,
                        ServoResult& result) noexcept {
  // Leave the robot where the caller put it, not somewhere on the spiral.
  const int before = result.moves;
  const Step back = walkTo(robot, planned, result);
  result.search_moves += result.moves - before;
  if (back == Step::kOk)
    latch(result, ServoStatus::kSpotNotFound, "spot not found; robot back at the planned pose");
}

bool PsdServo::acquire(ControllerLink& robot, PsdReader& psd, const Joints& planned,
                       const PsdSpot& expected, ServoResult& result) noexcept {
  bool failed = false;
  switch (sweep(robot, psd, planned, expected, result)) {
    case Sweep::kLit:
      return true;
    case Sweep::kFailed:
      return false;
    case Sweep::kNothing:
      notFound(robot, planned, result);
      return false;
    case Sweep::kNear:
      // Where the signal rose the reading is dark: the detector's edge is a pitch away at most.
      if (spiral(robot, psd, q_, Eigen::Vector2d::Zero(), options_.sweep_pitch_mm, result, &failed))
        return true;
      if (!failed) notFound(robot, planned, result);
      return false;
    case Sweep::kUnavailable:
      break;
  }
  // Point by point, from the planned pose (the search moves, if any, left it).
  if (maxAbs(toVector(q_) - toVector(planned)) > 1e-3) {
    if (walkTo(robot, planned, result) != Step::kOk) return false;
  }
  q_ = planned;  // not its float32 echo
  if (spiral(robot, psd, planned, toVector(expected), options_.search_radius_mm, result, &failed))
    return true;
  if (!failed) notFound(robot, planned, result);
  return false;
}

void PsdServo::fineServo(ControllerLink& robot, PsdReader& psd, bool aimed,
                         ServoResult& result) noexcept {
  law_->start(imageJacobian(cell_, psd_centre_, q_));
  const Eigen::Vector2d target = toVector(options_.target);
  bool settling = false;
  Eigen::Vector2d settle_uv = Eigen::Vector2d::Zero();
  // kZone stops at the reading after a move aimed to land within hit_zone_mm, not at the first
  // reading that happens to fall inside it. The recorded miss is that reading's repeatability
  // draw; stopping on the draw itself keeps only the draws that fell towards the zone, and the
  // recorded misses came out at 0.65 of the joints' variance (chi2/dof 0.65 over 8 ideal
  // worlds, 1.03 with a zone of 1 mm that never truncates), so every per-pose sigma was ~20%
  // too large. The aim depends only on the reading before the move, never on the draw recorded.
  // A reading beyond kRecordedWithinZones zones despite the aim (a Jacobian far off, a gross error)
  // is steered again: the PSD's orientation error times the reading is what a reading costs, 10 um
  // at 0.2 mm and 3 deg, and that tail is over 4 sigma of any pose's scatter. `aimed` says
  // whether the last move was aimed to land within the zone.

  for (;;) {
    const PsdReading& r = result.reading;
    const Eigen::Vector2d uv = toVector(r.spot);
    const Eigen::Vector2d e = uv - target;
    result.final_error_um = e.norm() * 1e3;
    if (!r.spot_present) {
      latch(result, ServoStatus::kSpotLost, "the spot left the detector");
      return;
    }
    if (r.in_valid_zone) {
      if (options_.stop == ServoStop::kCentre && e.norm() <= 1e-3 * options_.tolerance_um) break;
      if (options_.stop == ServoStop::kZone && aimed && e.norm() <= options_.recordedWithinMm()) {
        if (settling && (uv - settle_uv).norm() <= options_.settle_mm) break;
        // Read again without moving: a reading is only recorded once it repeats.
        settling = true;
        settle_uv = uv;
        law_->held();
        if (result.iterations >= options_.max_iterations ||
            r.time_s - result.acquired_s > options_.timeout_s) {
          latch(result, ServoStatus::kNotConverged, "the reading did not settle in time");
          return;
        }
        if (read(psd, result) != Step::kOk) return;  // no move since: nothing to settle
        ++result.iterations;
        continue;
      }
    }
    settling = false;
    if (result.iterations >= options_.max_iterations ||
        r.time_s - result.acquired_s > options_.timeout_s) {
      latch(result, ServoStatus::kNotConverged, "iterations or time exhausted");
      return;
    }
    // The law's correction, held to the step limit whatever law computed it.
    JointVector dq = law_->correction(e, r.in_valid_zone);
    const double largest = maxAbs(dq);
    const double scale = largest > options_.max_step_deg ? options_.max_step_deg / largest : 1.0;
    dq *= scale;
    // The law takes `gain` of the step to the target: it aims at (1 - gain * scale) e.
    aimed = r.in_valid_zone && (1 - options_.gain * scale) * e.norm() <= options_.hit_zone_mm;
    const Joints next = toJoints(toVector(q_) + dq);
    const JointVector sent = toVector(next) - toVector(q_);
    if (move(robot, next, result) != Step::kOk) return;
    law_->moved(sent);
    if (settledRead(psd, result) != Step::kOk) return;
    ++result.iterations;
  }
  result.status = ServoStatus::kConverged;
  result.q_deg = q_;
}

ServoResult PsdServo::run(ControllerLink& robot, PsdReader& psd, CellClock& clock,
                          const Joints& planned_deg, const PsdSpot& expected, bool aimed) noexcept {
  ServoResult result;
  clock_ = &clock;
  runCycle(robot, psd, planned_deg, expected, aimed, result);
  clock_ = nullptr;
  orderPath(result);
  return result;
}

ServoResult PsdServo::run(ControllerLink& robot, PsdReader& psd, const Joints& planned_deg,
                          const PsdSpot& expected, bool aimed) noexcept {
  ServoResult result;
  ring_count_ = ring_next_ = 0;
  if (options_.settle_s > 0)
    return latch(result, ServoStatus::kBadStart, "settle_s needs the clock overload of run()");
  runCycle(robot, psd, planned_deg, expected, aimed, result);
  orderPath(result);
  return result;
}

void PsdServo::runCycle(ControllerLink& robot, PsdReader& psd, const Joints& planned_deg,
                        const PsdSpot& expected, bool aimed, ServoResult& result) noexcept {
  ring_count_ = ring_next_ = 0;
  path_tail_next_ = 0;
  faulted_ = false;
  if (aborted(result) || readBack(robot, result) != Step::kOk) return;
  // The controller stores float32 and speaks 5 decimals: a few 1e-5 deg from the request.
  for (int i = 0; i < kJointCount; ++i) {
    if (!(std::abs(q_[i] - planned_deg[i]) <= 1e-3)) {
      latch(result, ServoStatus::kBadStart, "the robot is not at the planned pose");
      return;
    }
  }
  // Continue from the pose requested, not its float32 echo, so the recorded joints are exact.
  q_ = planned_deg;
  // The start of the servo is the end of the planned move: its settling counts as acquisition.
  const double t0 = clock_ != nullptr ? clock_->nowS() : 0.0;
  if (settledRead(psd, result) != Step::kOk) return;
  result.start_s = clock_ != nullptr ? t0 : result.reading.time_s;
  result.settle_acquisition_s = result.settle_s;
  if (result.path_count > 0) result.path[0].t_s = result.reading.time_s - result.start_s;
  // A search moved the arm since the aimed move: its end is not where the aim put the spot.
  if (!result.reading.spot_present) {
    aimed = false;
    if (!acquire(robot, psd, planned_deg, expected, result)) {
      result.acquired_s = result.end_s;
      return;
    }
  }
  result.acquired_s = result.reading.time_s;
  fineServo(robot, psd, aimed, result);
}

}  // namespace zerocal::servo
