// The simulated IRC5: a real TCP server speaking zerocal's RAPID module's protocol (and
// upstream open_abb's, without LF, behind a switch) over a sim::SimulatedArm, whose true pose
// differs from what it reports by the world's joint offsets. The server parses a request, calls
// the arm and formats its reply; the arm holds every state but the protocol's (the search
// spiral's rows, a restart asked for, the fault injection). Time is simulated: a move advances
// the simulated clock by what it costs a real IRC5 (irc5::MotionCosts: a fixed cost per move, the
// accelerating and braking profile, the settling at the fine point) and replies at once, unless
// real-time pacing is asked for.
//
// Runs in-process on its own I/O thread (start()) or on the caller's thread (run(), for the
// zerocal-sim program). The state accessors are thread-safe.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/irc5/motion_time.h"
#include "zerocal/model/robot.h"
#include "zerocal/sim/simulated_arm.h"
#include "zerocal/sim/world.h"

namespace zerocal {

// Fault injection. Every switch can be changed while the server runs (setFaults).
struct SimFaults {
  // Answer this many requests on a connection, then close it instead of answering the next;
  // -1 = never.
  int drop_after_requests = -1;
  // Wall-clock delay before every reply.
  std::chrono::milliseconds reply_delay{0};
  // Send each reply in three writes split_gap apart (separate TCP segments).
  bool split_replies = false;
  std::chrono::milliseconds split_gap{5};
  // Requests with this code get an unparsable reply; -1 = none.
  int garbage_code = -1;
  // Moves (codes 1 and 2) never reply, and the connection answers nothing more: the RAPID
  // server blocked inside a move.
  bool stall_moves = false;
  // The next drop_code_times requests with this code close their connection instead of being
  // answered (43: an external cell's beam-spot link alone); -1 = none.
  int drop_code = -1;
  int drop_code_times = 1;
};

// The arm's motor calibration (MOC MOTOR_CALIB cal_offset, requests 41, 45, 46, 48) and the spot
// search's light signal (requests 47 and 49, docs/irc5.md): the simulated arm's own
// (include/zerocal/sim/simulated_arm.h).
using SimMotorCalibration = sim::MotorCalibration;
using SimSearchSignal = sim::SearchSignal;

struct SimControllerOptions {
  World world;
  SimMotorCalibration motor;
  std::string address = "127.0.0.1";
  std::uint16_t port = 0;  // 0: an ephemeral port, see SimController::port()
  // false: replies end with no LF, like upstream's server.
  bool lf_terminated = true;
  // Wall-clock seconds a move's reply waits per simulated second of the move: 0 answers at once,
  // 1 in real time, 0.1 ten times faster (a demonstration one can follow).
  double pace = 0.0;
  // What each move costs beyond its distance over its speed (docs/simulated-cell.md).
  irc5::MotionCosts motion;
  SimSearchSignal search;
  // Simulated seconds a restart (request 46, RAPID WarmStart) takes before the RAPID server
  // listens again: charged to the simulated clock, and pace x this in wall time, during which
  // the controller refuses connections. A real IRC5's warm start takes tens of seconds
  // (docs/irc5.md: inferred, not measured).
  double restart_s = 30.0;
  // How long the controller has been running when it starts (s): the arm's warm-up carried in
  // (SimulatedArmOptions::warm_s); 0 cold.
  double warm_s = 0.0;
  // Seeds the repeatability noise.
  std::uint64_t seed = 1;
  // A request still missing its '#' after this long gets a bad-message reply and is discarded
  // (upstream would answer it with the previous request's code).
  std::chrono::milliseconds partial_request_timeout{1000};
  // Initial joints (deg), as the controller believes them.
  Joints start_joints{0, 0, 0, 0, 30, 0};
  std::string serial = "SIM-1600-0001";
  std::string software_version = "6.15.01.00";
  std::string robot_type = "IRB 1600-10/1.45";
  SimFaults faults;
};

using MotionTotals = sim::MotionTotals;

// The IRC5's timing (irc5::jointMoveSeconds and irc5::rampedSeconds with `costs`) as the simulated
// arm's motion model: what SimController gives its arm.
sim::MotionModel irc5MotionModel(const irc5::MotionCosts& costs);

class SimController {
 public:
  // Binds and listens at once (so port() is valid). Throws Error when the address cannot be
  // bound, ConfigError when the start joints are outside the robot's limits or the motion costs
  // are invalid.
  explicit SimController(SimControllerOptions options);
  ~SimController();
  SimController(const SimController&) = delete;
  SimController& operator=(const SimController&) = delete;

  // Serves on a new thread until stop() or destruction.
  void start();
  // Serves on the calling thread until stop() is called from another thread or, when
  // stop_on_signals, SIGINT or SIGTERM arrives.
  void run(bool stop_on_signals = false);
  // Closes the listener and every connection; run() returns. Idempotent.
  void stop();

  std::uint16_t port() const;
  void setFaults(const SimFaults& faults);

  // Joints as the controller believes them (the float32 values it stores), degrees.
  Joints commandedJoints() const;
  // The error of the last move (deg): its repeatability error plus, while a reading is taken
  // before the arm settled (World::gross), that error; true joints = commanded + offsets +
  // zeroShiftDeg() + gravity sag + this.
  Joints moveErrorDeg() const;
  // Where the detector sees the beam now: the true arm (beamHit at simTimeS()), shifted by stray
  // light while there is some.
  std::optional<BeamHit> beamHitNow() const;
  // MOC cal_offset values now (rad), as request 41 reports them.
  std::array<double, kJointCount> calOffsets() const;
  // Writes joint's (1..6) cal_offset (stored as a float32, as RAPID's num) and has the
  // controller take it, as a real one does after the restart that follows a MOC change: the
  // joint's true zero moves by (new - old) / k. Throws ConfigError (nothing changed) for a value
  // outside [0, 2 pi) or a joint whose true transmission is unknown.
  void writeCalOffset(int joint, double rad);
  // Updates the revolution counter of joint (1..6) with the joint at its synchronisation mark
  // (where it stood at q = 0 under the calibration it started with): the counter takes the motor
  // turn nearest to the calibration position, so a whole-turn error goes, the rest stays.
  void updateRevolutionCounter(int joint);
  // How far each joint's true zero has moved since start (deg): true joint angles are the
  // commanded ones plus world().true_offsets_deg plus this (plus the move's error).
  Joints zeroShiftDeg() const;
  // SimulatedArm::reseedNoise and noiseSeed: a session's own repeatability noise, gross errors
  // and latch latency.
  void reseedNoise(std::uint64_t seed);
  std::uint64_t noiseSeed() const;
  // The PSD is moved to `placement` (1-based) of a session whose placements are planned at
  // `planned_centres_mm` (placement 1's first): placement 1 is where the world has it; each
  // further one's truth is drawPlacement(world, seed, placement, planned centre). world() then
  // lists the session's placements (none for one) with the PSD at `placement`. Call it from the
  // thread that drives the cell, between moves. Throws ConfigError for a placement outside
  // 1..the centres given.
  void placePsd(int placement, const std::vector<Eigen::Vector3d>& planned_centres_mm);
  // Simulated seconds since construction (advanced by moves only).
  double simTimeS() const;
  MotionTotals motionTotals() const;
  // Restarts (request 46) begun since construction.
  long restartCount() const;
  // Requests answered or dropped, over all connections.
  long requestCount() const;
  long connectionCount() const;
  const World& world() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> impl_;
};

}  // namespace zerocal
