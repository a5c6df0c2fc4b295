// The simulated arm: a six-joint robot and the controller state that moves it, with no
// controller's protocol. A controller's fake is a thin wire layer over one SimulatedArm: it
// parses a request, calls the arm and formats the reply (SimController does so for the IRC5's
// RAPID module); the arm knows no request number and no wire text.
//
// What it holds:
// - the joints as the controller believes them (deg), its tool and work object, its speed;
// - joint, linear and search moves, each refused without moving when a target lies beyond the
//   robot's limits, each charged to the arm's clock by the injected MotionModel;
// - the true arm: true joints = joints() + world().true_offsets_deg + zeroShiftDeg() + gravity
//   sag + moveErrorDeg(), and beamHitNow() where that arm puts the laser on the PSD;
// - the motor calibration: per joint the offset between motor and joint angle (rad, [0, 2 pi),
//   an IRC5's MOC cal_offset) and the true transmission k (motor angle per joint angle), a
//   configuration written offsets wait in until restart(), and revolution counters;
// - the controller's identity (RobotInfo) as data.
//
// Time is simulated: a move returns at once and advances timeS() by its cost; nothing sleeps.
// Thread-safe: every member function is atomic under one lock, so a server's I/O thread can move
// the arm while a test or the simulated cell reads it. world() is the exception (see there).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/cell/controller_link.h"
#include "zerocal/cell/search_move.h"
#include "zerocal/model/robot.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/world.h"

namespace zerocal::sim {

// The speed of the moves: the TCP's along its path and the tool's reorientation.
struct MoveSpeed {
  double tcp_mm_s = 100;
  double ori_deg_s = 50;
};

// One move's simulated duration, by where the time goes (s).
struct MoveCost {
  double motion_s = 0;    // accelerating, cruising, braking
  double overhead_s = 0;  // the controller's fixed cost per move
  double settle_s = 0;    // in position at the fine point
  double total() const { return motion_s + overhead_s + settle_s; }
};

// How long moves take, injected so that the arm holds no controller's timing model: an IRC5's
// (irc5::jointMoveSeconds, irc5::rampedSeconds, irc5::MotionCosts) is also the IRC5 client's
// deadline model, so it stays in drivers/irc5 with one definition, and another controller's fake
// can give the arm its own. SimController wires the IRC5's (irc5MotionModel, sim_controller.h).
//
// With `largest` the largest change of any joint from the move's start (deg), a move costs
//
//   joint move:   profile_s(cruise_s(from, to, speed), largest) + overhead_s + settle_s
//   linear move:  profile_s(max(distance / tcp_mm_s, turn / ori_deg_s), largest) + ...
//   search move:  profile_s(sum of cruise_s over its waypoints at the search's speed, largest),
//                 cut where the arm stopped after the latch, + overhead_s + settle_s
struct MotionModel {
  // Seconds a joint-space line from `from` to `to` (deg) takes at constant speed (no ramps).
  std::function<double(const Robot& robot, const Joints& from, const Joints& to,
                       const MoveSpeed& speed)>
      cruise_s;
  // Seconds a path that takes cruise_s at constant speed takes with the joints accelerating and
  // braking, when the joint that moves most moves largest_joint_deg (deg).
  std::function<double(double cruise_s, double largest_joint_deg)> profile_s;
  double overhead_s = 0;  // fixed, every move (s)
  double settle_s = 0;    // at the fine point, every move (s)

  // Empty when usable, else the first problem.
  std::string validate() const;
};

// The arm's motor calibration at start (docs/apply.md). The controller's joint angle is
// (motor angle - cal_offset) / k, so a new cal_offset moves the joint's true zero by
// (new - old) / k with the arm's true k, whatever k the robot's configuration believes: a wrong
// sign or ratio there leaves the error it would leave on a real robot. The revolution counter
// keeps counting from its motor turn until it is updated.
struct MotorCalibration {
  // The cal_offset values at start (rad, [0, 2 pi)); nullopt: drawn from the seed, uniform.
  std::optional<std::array<double, kJointCount>> cal_offset_rad;
  // The arm's true transmission; nullopt: the robot model's (0 where it gives none: such a
  // joint's cal_offset cannot be written).
  std::optional<std::array<double, kJointCount>> transmission;
};

// The spot search's light signal (docs/irc5.md): a comparator on the PSD amplifier's SUM output
// wired to a digital input of the controller, whose rising edge latches the joints during a
// search move. The arm evaluates the detector's noise-free SUM along the move's path.
struct SearchSignal {
  bool wired = true;         // false: the controller has no such input; searches are refused
  PsdModelOptions psd;       // the detector the comparator watches
  double threshold_v = 0.5;  // the comparator's threshold (the chain's daq.sum_threshold_v)
  // From the light crossing the threshold to the joints latched (s): the input's filter, the
  // I/O cycle and the interrupt, uniform in [min, max] (inferred, docs/irc5.md).
  double latency_min_s = 0.002, latency_max_s = 0.012;
};

struct SimulatedArmOptions {
  World world;
  MotorCalibration motor;
  SearchSignal search;
  MotionModel motion;  // required: no default timing model
  // Simulated seconds restart() charges to the clock.
  double restart_s = 30.0;
  // The controller's time at construction (s): how long the arm has been working already, so
  // that its thermal state (World::thermal, a function of the controller's time) is that of a
  // warm arm; 0 a cold one. 0..kMaxWarmS.
  double warm_s = 0.0;
  // Seeds the repeatability noise, the gross errors, the latch latency and drawn cal_offsets.
  std::uint64_t seed = 1;
  // Initial joints (deg), as the controller believes them; within the robot's limits.
  Joints start_joints{0, 0, 0, 0, 30, 0};
  // true: the controller keeps joints and offsets as 32-bit floats (an IRC5's RAPID num), so
  // every stored joint target, latched joint and cal_offset is rounded to float
  // (roundToFloat32); false: doubles.
  bool single_precision = false;
  RobotInfo identity;  // what the controller reports itself as
};

// Where the simulated time of the moves went, summed over every move since construction.
struct MotionTotals {
  long moves = 0;  // search moves included
  long search_moves = 0;
  double motion_s = 0, overhead_s = 0, settle_s = 0;
};

// Why a move did not move the arm.
enum class MoveRefusal {
  kNone,            // it moved
  kOutOfLimits,     // a target (a search's waypoint included) beyond the robot's limits
  kUnreachable,     // a linear move's target has no joint solution, near the arm's, in the limits
  kBadPath,         // a search's run gives no waypoint, or more than 4999
  kNoSearchSignal,  // a search without a wired SearchSignal
};

struct MoveResult {
  MoveRefusal refusal = MoveRefusal::kNone;
  MoveCost cost;  // charged to the clock; zero when refused
  // A search move: the joints (deg, as stored) latched when the light rose; nullopt when it
  // did not rise (the arm then ran the whole spiral) or for other moves.
  std::optional<Joints> latched_deg;
  bool moved() const { return refusal == MoveRefusal::kNone; }
};

// Why a cal_offset was not written.
enum class CalOffsetRefusal {
  kNone,
  kNoSuchJoint,          // joint outside 1..6
  kOutOfRange,           // the value (as stored) outside [0, 2 pi)
  kTransmissionUnknown,  // the arm's true transmission of that joint is 0
};

// v as a 32-bit float holds it.
double roundToFloat32(double v);

class SimulatedArm {
 public:
  // Throws ConfigError (every problem of the motor calibration, else the first other) when the
  // motion model is unusable, restart_s is outside 0..3600 s, warm_s outside 0..kMaxWarmS, a
  // cal_offset is outside [0, 2 pi) or the start joints are outside the robot's limits.
  explicit SimulatedArm(SimulatedArmOptions options);
  ~SimulatedArm();
  SimulatedArm(const SimulatedArm&) = delete;
  SimulatedArm& operator=(const SimulatedArm&) = delete;

  // --- Moves: each ends at rest at a fine point with a new repeatability error drawn. ---

  // Joint move (MoveAbsJ) to target_deg as stored.
  MoveResult moveJoints(const Joints& target_deg);
  // Linear move (MoveL) of the tool to `target` (in the work object frame; the quaternion is
  // normalised, a zero one taken as identity), through the joint solution nearest the arm's
  // current joints.
  MoveResult moveLinear(const TcpPose& target);
  // Search move: the waypoints of `run` on `spiral` (each stored as a joint target), at
  // run.speed_mm_s, stopping where the light signal's rising edge latched the joints (after the
  // waypoint queued when it did). Expects a valid run: pitch > 0, 0 <= from <= to, speed > 0.
  MoveResult searchRun(const SpotSearch& spiral, const SearchRun& run);

  // --- The controller's settings for the moves. ---

  // The tool frame in the flange frame (mm, unit quaternion), used by moveLinear and toolPose.
  void setTool(const TcpPose& tool_in_flange);
  // The work object frame in the base frame.
  void setWorkObject(const TcpPose& wobj_in_base);
  // Expects both speeds > 0.
  void setSpeed(const MoveSpeed& speed);
  MoveSpeed speed() const;

  // --- State. ---

  // The joints as the controller believes them (deg, as stored).
  Joints joints() const;
  // The tool pose at joints() in the work object frame (quaternion with w >= 0).
  TcpPose toolPose() const;
  // The error of the last move (deg): its repeatability error plus, while a reading is taken
  // before the arm settled (World::gross), that error.
  Joints moveErrorDeg() const;
  // Where the detector sees the beam now: the true arm (beamHit at timeS()), shifted by stray
  // light while there is some.
  std::optional<BeamHit> beamHitNow() const;
  bool searchSignalWired() const;
  // The controller's simulated time (s): options.warm_s at construction, then every move's cost
  // and every restart's duration. The arm's thermal state follows it.
  double timeS() const;
  MotionTotals motionTotals() const;
  const RobotInfo& identity() const;
  std::uint64_t seed() const;
  // Starts the per-session random draws (the repeatability noise, the gross errors, the latch
  // latency and where the PSD sits on its base, World::psd_seated_mm) afresh from `seed`, as if the
  // arm had been built with it; what the seed fixed of the cell (the drawn cal_offsets, the PSD's
  // further placements) stays. A session's own noise (docs/simulated-cell.md).
  void reseedNoise(std::uint64_t seed);
  // The seed the per-session draws last started from: options.seed until reseedNoise.
  std::uint64_t noiseSeed() const;
  // The world (its robot's limits, the PSD). placePsd changes its placements: read it from the
  // thread that drives the cell, or when nothing places the PSD.
  const World& world() const;

  // --- Motor calibration (joint 1..6, rad). ---

  // The cal_offset values in effect.
  std::array<double, kJointCount> calOffsets() const;
  // The configuration's values: those in effect, where written ones wait for restart().
  std::array<double, kJointCount> configuredCalOffsets() const;
  // Writes joint's cal_offset (stored) into the configuration; restart() takes it.
  CalOffsetRefusal configureCalOffset(int joint, double rad);
  // Writes joint's cal_offset and takes it at once, as after a restart but without its time:
  // the joint's true zero moves by (new - old) / k. Throws ConfigError (nothing changed) where
  // configureCalOffset would refuse.
  void takeCalOffset(int joint, double rad);
  // A restart of the controller: takes every configured cal_offset and charges restart_s to the
  // clock. Returns restart_s.
  double restart();
  // Restarts since construction.
  long restartCount() const;
  // Each motor's angle behind joints() (rad, within one motor turn [0, 2 pi)): cal_offset +
  // k q with the arm's true k.
  std::array<double, kJointCount> motorAnglesRad() const;
  // Updates the revolution counter of joint (1..6) with the joint at its synchronisation mark
  // (where it stood at q = 0 under the calibration it started with): the counter takes the motor
  // turn nearest to the calibration position, so a whole-turn error goes, the rest stays. Throws
  // ConfigError for a joint outside 1..6; does nothing where the transmission is unknown.
  void updateRevolutionCounter(int joint);
  // How far each joint's true zero has moved since start (deg).
  Joints zeroShiftDeg() const;

  // --- The cell. ---

  // The PSD is moved to `placement` (1-based) of a session whose placements are planned at
  // `planned_centres_mm` (placement 1's first): placement 1 is where the world has it; each
  // further one's truth is drawPlacement(world, seed, placement, planned centre). world() then
  // lists the session's placements (none for one) with the PSD at `placement`. Call it between
  // moves. Throws ConfigError for a placement outside 1..the centres given.
  void placePsd(int placement, const std::vector<Eigen::Vector3d>& planned_centres_mm);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace zerocal::sim
