// The PSD servo: from a planned pose, find the laser spot on the PSD (acquisition) and bring it to
// the detector's centre (fine servo), with small joint moves the caller can bound.
//
// Acquisition when SUM is below threshold at the planned pose, out to `search_radius_mm` around
// the planned pose (or around where the caller expects the spot):
//
// - Continuous search, where the controller offers it (the PSD's light signal wired to one of
//   its inputs; ControllerLink::startSpotSearch, zerocal/cell/search_move.h) and
//   `sweep_speed_mm_s` > 0: the same spiral mapping as below with turns `sweep_pitch_mm` apart,
//   driven without stopping in runs of growing radius (each about 3 s, so that an abort waits
//   little), the controller latching the joints where the light rose. The 10 mm detector is lit
//   with the spot's centre up to ~5.7 mm from its centre, so an 8 mm pitch passes every point
//   within 4 mm: a handful of moves to 100 mm instead of hundreds of points. The robot then steps
//   back to the latched joints and a settled reading there starts the fine servo; should it be
//   dark, a point-by-point spiral of one pitch around them. A spiral that ends dark is driven
//   once more turned half a turn, its turns between the first one's (the linearised mapping
//   spreads them far out).
// - Otherwise a discrete Archimedean spiral, points `search_step_mm` apart along the path and
//   between turns. Every point is a move, and a move costs a real controller about half a second
//   whatever its length (docs/simulated-cell.md), so the spacing follows the detector, not the
//   spot: 4 mm leaves no point of the plane farther than 2.8 mm from a search point, with room
//   for the linearised model's error far out (7 mm missed the spot in 4 of 10 seeded worlds,
//   5 mm one 58 mm out in seed 41). The spiral is mapped to joints through the model's image
//   Jacobian at the planned pose.
//
// Not found within the bounds: the robot is walked back to the planned pose and the fault
// latched.
//
// Fine servo: a ServoLaw (servo_law.h) turns each steering reading into a joint correction; the
// default, CorrectedJacobianLaw, is this: e = (u, v) - target; dq = -gain J^+ e, with J = d(u,
// v)/dq the image Jacobian predicted by the nominal kinematics and laser through the PSD's known
// orientation, and J^+ its minimum-norm pseudo-inverse (damped). The model is a little wrong (the
// PSD's orientation and distance as taught, the laser's mounting, the offsets being calibrated),
// mostly as a rotation and scale of the spot's motion; so the servo steers with A J, where the 2 x
// 2 A is fitted online to every observed motion de of a move dq, p = J dq:
//
//   A = (sum de p^T + w^2 I) (sum p p^T + w^2 I)^-1,  w = jacobian_prior_mm,
//
// only from moves between two readings in the valid zone. The prior term keeps A = I until the
// predicted motions add up to more than w: a move's own error at the PSD (robot repeatability,
// ~0.03 mm) is as large as a fine-servo step, and a rank-one Broyden update of J from such steps
// was measured to lose the spot (docs/servo.md); two numbers per axis fitted to all the moves
// average that error out.
//
// Every move is checked before it is sent: no joint moves more than max_step_deg (longer walks
// are split), and no target lies outside the limits less limit_margin_deg.
//
// Settling: a reading that steers the fine servo or may be recorded is taken at least settle_s
// of cell time after the last move (the clock's waitS()): at the start, after the spot is
// found, after every fine-servo move. Search readings only ask whether the spot is on the detector
// and are taken at once: a settling arm still lights it.
//
// Abort: `abort` (when set) is polled before every move and every reading; once it is true no
// further move is sent, the robot stays at rest where the last move ended (a pose checked against
// the limits) and kAborted is returned. An atomic load neither allocates nor locks.
//
// Real-time discipline: run() allocates, locks, logs and throws nothing of its own; time comes
// from the readings' cell clock, never the wall clock. Errors thrown by the seams (link, DAQ) are
// caught at the cycle's edge and latched as a fault with the last kFaultHistory samples. The
// seams themselves (a TCP client, a USB command) may allocate; that is theirs to avoid.
#pragma once

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstddef>
#include <string>

#include "zerocal/calib/cell_model.h"
#include "zerocal/cell/controller_link.h"
#include "zerocal/cell/link_error.h"
#include "zerocal/cell/psd_reader.h"
#include "zerocal/psd/spot.h"
#include "zerocal/servo/servo_law.h"
#include "zerocal/servo/servo_sample.h"

namespace zerocal::servo {

// d(u, v)/dq of the nominal laser (cell.laser, zero offsets) on the plane through psd_centre_mm
// (base frame) with the cell's PSD orientation, by central differences.
ImageJacobian imageJacobian(const CellModel& cell, const Eigen::Vector3d& psd_centre_mm,
                            const Joints& q_deg);

enum class ServoStop {
  kCentre,  // stop within tolerance_um of the target
  kZone,    // stop at a settled reading inside the valid zone within hit_zone_mm of the target
};

// The servo's options. The first group is the configuration's `servo` section itself: key for
// key the same names, units and defaults (docs/configuration.md), so that a parameter is one
// field here and one line of the configuration's schema. The rest are fixed by the method or set
// by the caller.
struct ServoOptions {
  ServoStop stop = ServoStop::kZone;
  double tolerance_um = 2.0;  // kCentre
  double max_step_deg = 0.5;  // largest joint change of any single move
  int max_iterations = 40;
  double timeout_s = 20;  // fine servo, from acquisition, cell clock
  // Cell time waited after a move before a reading that counts (see above); needs the clock
  // given to run().
  double settle_s = 0.2;
  // Offsets of 1 deg, the laser's mounting and the teaching error miss by up to ~55 mm at the
  // default plan's first pose, but by more than 60 mm at the first pose of a 12-pose plan on two
  // of ten seeded worlds (seeds 2 and 5, the spot then not found); the spiral stops where the
  // spot lights the detector, so the wider radius costs only sessions that would fault.
  double search_radius_mm = 100.0;
  double search_step_mm = 4.0;
  // At ~0.5 s a point the point-by-point spiral reaches about 78 mm in this time; the continuous
  // search covers the whole radius in about 40 s.
  double search_time_s = 600;
  // The continuous search (above): speed along the path, 0 for the discrete spiral only; the
  // distance between its turns.
  double sweep_speed_mm_s = 100.0;
  double sweep_pitch_mm = 8.0;
  double gain = 0.9;         // below 1: no overshoot from a slightly wrong Jacobian
  double damping_mm = 1e-3;  // Tikhonov term of the pseudo-inverse (mm/deg)^2 scale

  PsdSpot target;  // where the fine servo brings the spot, PSD frame (mm)
  // kZone: the servo stops at the reading after a move aimed to land this close to the target
  // (docs/servo.md), once it lies within recordedWithinMm().
  double hit_zone_mm = 0.05;
  // kZone: two readings at the same pose agreeing within this are settled.
  double settle_mm = 0.005;
  double limit_margin_deg = 1.0;   // kept from every joint limit (controller.irc5.limit_margin_deg)
  bool correct_jacobian = true;    // fit A (above); false: the model's J throughout
  double jacobian_prior_mm = 0.3;  // w above: the motion that weighs as much as the model
  int max_search_points = 3000;

  // Polled each cycle; may be null. Must outlive every run().
  const std::atomic<bool>* abort = nullptr;

  // Empty when usable, else the first problem.
  std::string validate() const;
  // How far from the target a recorded reading may lie: tolerance_um (kCentre), or
  // kRecordedWithinZones zones (kZone: the arm's scatter lands an aimed move beyond the zone).
  double recordedWithinMm() const;
};
inline constexpr double kRecordedWithinZones = 4.0;

enum class ServoStatus {
  kConverged,
  kSpotNotFound,  // acquisition exhausted; robot back at the planned pose
  kSpotLost,      // the spot left the detector during the fine servo
  kNotConverged,  // iterations or time exhausted
  kLimit,         // a needed move would leave the limits less the margin
  kLinkError,     // the controller link threw
  kSensorError,   // the PSD reader threw
  kBadStart,      // options invalid or the robot not where planned
  kAborted,       // the abort flag was set; the robot at rest where the last move ended
};
const char* statusName(ServoStatus status) noexcept;

constexpr std::size_t kFaultHistory = 32;

// A latched fault: what went wrong and the samples leading to it (oldest first).
struct ServoFault {
  ServoStatus status = ServoStatus::kConverged;
  const char* message = "";  // static text
  // kLinkError and kSensorError: what the link's LinkError said may be done (kFatal when the
  // device threw anything else).
  LinkError::Kind link_kind = LinkError::Kind::kFatal;
  // kLinkError and kSensorError: what the exception said (cut to fit; empty for none), so that
  // the session can name the cause, a link to the controller say, beside the servo's message.
  std::array<char, 192> detail{};
  std::array<ServoSample, kFaultHistory> samples{};
  std::size_t sample_count = 0;
};

// The spot's path kept per run, for the report (t_s: cell time since the servo's start): the
// first kPathHead and the last kPathCapacity - kPathHead readings with the spot on the detector
// (outside the map's zone u, v are the chain's coarse estimate).
constexpr std::size_t kPathCapacity = 64;
constexpr std::size_t kPathHead = 16;

struct ServoResult {
  ServoStatus status = ServoStatus::kBadStart;
  Joints q_deg{};      // commanded joints at the end
  PsdReading reading;  // the last reading (the one to record when converged)
  int moves = 0;       // all moves sent, search and return included
  int search_moves = 0;
  int iterations = 0;  // fine-servo cycles (readings taken after acquisition)
  int readings = 0;
  double final_error_um = 0;                      // |(u, v) - target| of the last reading
  double start_s = 0, acquired_s = 0, end_s = 0;  // cell clock
  // Cell time waited for settling, in all and before acquired_s.
  double settle_s = 0, settle_acquisition_s = 0;
  // Spot path: path[0, path_count) in time order; path_skipped readings between the head and the
  // tail were not kept.
  std::array<SpotPathPoint, kPathCapacity> path{};
  std::size_t path_count = 0;
  int path_skipped = 0;
  // Search and fine servo, settling excluded: move + acquisition + servo + settle is the whole.
  double acquisitionS() const { return acquired_s - start_s - settle_acquisition_s; }
  double servoS() const { return end_s - acquired_s - (settle_s - settle_acquisition_s); }
  bool ok() const { return status == ServoStatus::kConverged; }
};

class PsdServo {
 public:
  // `psd_centre_mm`: the PSD's centre in the base frame as taught (a few mm off is fine; it only
  // sets the plane of the predicted Jacobian). Copies what it needs; run() allocates nothing.
  // The fine servo steers with CorrectedJacobianLaw over the options' gain, damping_mm,
  // correct_jacobian and jacobian_prior_mm. Throws ConfigError for invalid options.
  PsdServo(const CellModel& cell, const Eigen::Vector3d& psd_centre_mm, ServoOptions options);
  // The same loop steering with `law`, which must outlive the servo.
  PsdServo(const CellModel& cell, const Eigen::Vector3d& psd_centre_mm, ServoOptions options,
           ServoLaw& law);
  // The law is referred to by address (the servo's own, or the caller's).
  PsdServo(const PsdServo&) = delete;
  PsdServo& operator=(const PsdServo&) = delete;

  // The robot must stand at `planned_deg` (what the caller last moved it to). `expected`:
  // where the spot is expected at the planned pose (PSD frame, e.g. from SpotPredictor); the
  // search is centred on it when the spot is not seen at once. Never throws. On anything but
  // kConverged the fault is latched (fault()) until the next run(). `clock` waits settle_s; the
  // overload without one returns kBadStart when settle_s is not 0. `aimed`: the planned move was
  // aimed to land the spot within hit_zone_mm by a prediction as good as the arm's scatter
  // (SpotPredictor::predictsFromReading); kZone then counts it as the aimed move it stops after,
  // and a pose the spot lands on as predicted is recorded without a servo move.
  ServoResult run(ControllerLink& robot, PsdReader& psd, CellClock& clock,
                  const Joints& planned_deg, const PsdSpot& expected = {},
                  bool aimed = false) noexcept;
  ServoResult run(ControllerLink& robot, PsdReader& psd, const Joints& planned_deg,
                  const PsdSpot& expected = {}, bool aimed = false) noexcept;

  bool faulted() const noexcept { return faulted_; }
  const ServoFault& fault() const noexcept { return fault_; }
  const ServoOptions& options() const noexcept { return options_; }

 private:
  enum class Step { kOk, kFailed };
  Step move(ControllerLink& robot, const Joints& target, ServoResult& result) noexcept;
  Step walkTo(ControllerLink& robot, const Joints& target, ServoResult& result) noexcept;
  Step read(PsdReader& psd, ServoResult& result) noexcept;
  // Waits settle_s (when a clock was given), then reads.
  Step settledRead(PsdReader& psd, ServoResult& result) noexcept;
  bool aborted(ServoResult& result) noexcept;
  void runCycle(ControllerLink& robot, PsdReader& psd, const Joints& planned,
                const PsdSpot& expected, bool aimed, ServoResult& result) noexcept;
  void keepPathPoint(const PsdReading& reading, ServoResult& result) noexcept;
  void orderPath(ServoResult& result) const noexcept;
  bool acquire(ControllerLink& robot, PsdReader& psd, const Joints& planned,
               const PsdSpot& expected, ServoResult& result) noexcept;
  enum class Sweep {
    kUnavailable,  // no continuous search here: search point by point
    kLit,          // the spot on the detector, a settled reading taken
    kNear,         // the signal rose, but the reading where it rose is dark
    kNothing,      // the whole spiral without a signal
    kFailed,       // latched
  };
  Sweep sweep(ControllerLink& robot, PsdReader& psd, const Joints& planned, const PsdSpot& expected,
              ServoResult& result) noexcept;
  // One spiral: to its centre, then its runs.
  Sweep sweepPass(ControllerLink& robot, PsdReader& psd, const SpotSearch& search,
                  ServoResult& result) noexcept;
  // The discrete spiral around `base` + J^+ (offset - expected_uv), out to radius_mm; true when
  // a settled reading sees the spot. False with nothing latched when the spiral ends dark.
  bool spiral(ControllerLink& robot, PsdReader& psd, const Joints& base,
              const Eigen::Vector2d& expected_uv, double radius_mm, ServoResult& result,
              bool* failed) noexcept;  // the centre was read already
  // q_ from the controller (after moves it interpolated itself), or the fault latched.
  Step readBack(ControllerLink& robot, ServoResult& result) noexcept;
  // Walks back to the planned pose and latches kSpotNotFound.
  void notFound(ControllerLink& robot, const Joints& planned, ServoResult& result) noexcept;
  // `aimed`: the move that ended where the fine servo starts was aimed into the zone.
  void fineServo(ControllerLink& robot, PsdReader& psd, bool aimed, ServoResult& result) noexcept;
  ServoResult& latch(ServoResult& result, ServoStatus status, const char* message) noexcept;
  // latch() from inside a catch handler, keeping the LinkError's kind of the exception in flight.
  void latchLinkError(ServoResult& result, ServoStatus status, const char* message) noexcept;
  void record(const PsdReading& reading) noexcept;

  CellModel cell_;
  Eigen::Vector3d psd_centre_;
  ServoOptions options_;
  CorrectedJacobianLaw default_law_;
  ServoLaw* law_;
  CellClock* clock_ = nullptr;      // during run() only
  std::size_t path_tail_next_ = 0;  // where the next tail point goes once the path is full
  Joints q_{};                      // commanded joints
  std::array<ServoSample, kFaultHistory> ring_{};
  std::size_t ring_next_ = 0, ring_count_ = 0;
  bool faulted_ = false;
  ServoFault fault_;
};

}  // namespace zerocal::servo
