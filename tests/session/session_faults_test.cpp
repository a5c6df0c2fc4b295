// Faults of a whole session on the simulated cell (real Irc5Client over TCP to the simulated
// controller, real USB-1408FS driver over the byte-exact simulated board, real journal): the link
// dropped, the board unplugged, the spot never found, abort in every phase.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "stored_plan.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/session/calibration_run.h"
#include "zerocal/sim/simulated_rig.h"

namespace zerocal {
namespace {

// The ideal world: these tests judge recovery from faults by the accuracy of the result, which the
// realistic world's model errors would blur (docs/simulated-cell.md).
sim::SimulatedCellOptions cellOptions(std::uint64_t seed) {
  return sim::seededCellOptions(seed, WorldKind::kIdeal);
}

struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-faults-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

// Forwards to the real client and keeps every joint target sent.
class RecordingLink final : public ControllerLink {
 public:
  explicit RecordingLink(ControllerLink& inner) : inner_(inner) {}
  void ping() override { inner_.ping(); }
  RobotInfo robotInfo() override { return inner_.robotInfo(); }
  Joints readJoints() override { return inner_.readJoints(); }
  void moveJoints(const Joints& target) override {
    moves.push_back(target);
    inner_.moveJoints(target);
  }
  TcpPose readPose() override { return inner_.readPose(); }
  void moveLinear(const TcpPose& target) override { inner_.moveLinear(target); }
  std::vector<Joints> moves;

 private:
  ControllerLink& inner_;
};

// Forwards to the real client; every request first waits `delay_s` of cell time, as one over a
// congested network to a real controller, whose cell clock is the wall.
class SlowLink final : public ControllerLink {
 public:
  SlowLink(ControllerLink& inner, CellClock& clock) : inner_(inner), clock_(clock) {}
  void ping() override {
    clock_.waitS(delay_s);
    inner_.ping();
  }
  RobotInfo robotInfo() override {
    clock_.waitS(delay_s);
    return inner_.robotInfo();
  }
  Joints readJoints() override {
    clock_.waitS(delay_s);
    return inner_.readJoints();
  }
  void moveJoints(const Joints& target) override {
    clock_.waitS(delay_s);
    inner_.moveJoints(target);
  }
  TcpPose readPose() override {
    clock_.waitS(delay_s);
    return inner_.readPose();
  }
  void moveLinear(const TcpPose& target) override {
    clock_.waitS(delay_s);
    inner_.moveLinear(target);
  }
  double delay_s = 0;

 private:
  ControllerLink& inner_;
  CellClock& clock_;
};

// Forwards to the real chain; runs `before_read` (with the number of the read, from 1) first.
class HookedPsd final : public PsdReader {
 public:
  explicit HookedPsd(PsdReader& inner) : inner_(inner) {}
  PsdReading read() override {
    ++reads;
    if (before_read) before_read(reads);
    return inner_.read();
  }
  std::function<void(int)> before_read;
  int reads = 0;

 private:
  PsdReader& inner_;
};

enum class Taught { kRight, k100MmOff };

// One session on a rig with the simulated cell's default noise: the knowledge a technician gives
// (with the PSD centre taught 100 mm off in x when asked), the optimal plan for it (stored in
// tests/data/plans), the daemon's default settings (hit-point mode, settling), a journal in a
// fresh folder. Recovery hooks are set by each test.
struct Session {
  explicit Session(std::uint64_t seed, Taught taught = Taught::kRight)
      : rig(cellOptions(seed)), given(sim::knowledgeOf(rig.cell.world())) {
    std::string plan_name = "ideal-" + std::to_string(seed);
    if (taught == Taught::k100MmOff) {
      given.taught_centre.x() += 100;
      plan_name += "-taught-100mm-off";
    }
    plan = testing::storedPlan(plan_name);
    settings = service::runSettingsOf(DaemonConfig{});
  }
  RunOutcome run(ControllerLink& link, PsdReader& psd,
                 const std::function<void(CalibrationRun&)>& setup = {}) {
    Journal journal(dir.path + "/journal.jsonl");
    CalibrationRun r(given.cell, given.taught_centre, plan, settings, journal);
    if (setup) setup(r);
    return r.run(link, psd, rig.cell, abort);
  }
  std::vector<PoseRecord> journalled() const {
    return readJournal(dir.path + "/journal.jsonl").records;
  }

  sim::SimulatedRig rig;
  sim::SessionKnowledge given;
  std::vector<Pose> plan;
  RunSettings settings;
  TempDir dir;
  std::atomic<bool> abort{false};
};

void expectPosesOnceEach(const std::vector<PoseRecord>& records, std::size_t count) {
  ASSERT_EQ(records.size(), count);
  for (std::size_t i = 0; i < records.size(); ++i) EXPECT_EQ(records[i].index, static_cast<int>(i));
}

void expectAt(const Joints& now, const Joints& expected) {
  for (int j = 0; j < kJointCount; ++j) EXPECT_NEAR(now[j], expected[j], 1e-4) << "joint " << j + 1;
}

void expectWithinThreeSigma(const RunOutcome& out, const World& world) {
  ASSERT_TRUE(out.report.has_value());
  ASSERT_TRUE(out.report->converged);
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& e = out.report->parameters[k];
    EXPECT_LE(std::abs(e.value - world.true_offsets_deg[k + 1]), 3 * e.sigma) << e.name;
  }
}

TEST(SessionFaults, LinkDroppedMidServoIsReconnectedAndThePoseDoneAgain) {
  Session s(24);
  SimController& controller = s.rig.cell.controller();
  ASSERT_EQ(controller.connectionCount(), 1);
  int dropped_at_pose = -1;
  s.settings.reconnect_link = [&] {
    controller.setFaults(SimFaults{});  // the cable is back
    s.rig.client.reconnect();
  };
  const RunOutcome out = s.run(s.rig.client, s.rig.psd, [&](CalibrationRun& run) {
    run.on_phase = [&](int i, RunPhase phase) {
      if (i != 2 || phase != RunPhase::kServoing || dropped_at_pose >= 0) return;
      // All requests so far went over the first connection: it answers the servo's joint
      // read-back, then closes instead of answering its first move.
      SimFaults f;
      f.drop_after_requests = static_cast<int>(controller.requestCount()) + 1;
      controller.setFaults(f);
      dropped_at_pose = i;
    };
  });
  ASSERT_EQ(out.state, RunState::kCompleted) << out.message;
  EXPECT_EQ(dropped_at_pose, 2);
  EXPECT_EQ(out.reconnects, 1);
  EXPECT_GE(controller.connectionCount(), 2);
  expectPosesOnceEach(s.journalled(), s.plan.size());
  expectWithinThreeSigma(out, s.rig.cell.world());
}

TEST(SessionFaults, LinkThatStaysDownFaultsNamingThePoseWithTheRobotAtRest) {
  Session s(24);
  SimController& controller = s.rig.cell.controller();
  s.settings.reconnect_link = [&] { s.rig.client.reconnect(); };
  s.settings.recovery_attempts = 2;
  Joints move_end{};
  const RunOutcome out = s.run(s.rig.client, s.rig.psd, [&](CalibrationRun& run) {
    run.on_phase = [&](int i, RunPhase phase) {
      if (i != 2 || phase != RunPhase::kServoing) return;
      move_end = controller.commandedJoints();
      SimFaults f;
      f.drop_after_requests = 0;  // this connection and every new one close at once
      controller.setFaults(f);
    };
  });
  EXPECT_EQ(out.state, RunState::kFaulted);
  EXPECT_NE(out.message.find("pose 3 of 8"), std::string::npos) << out.message;
  EXPECT_NE(out.message.find("reconnecting failed 2 times"), std::string::npos) << out.message;
  EXPECT_EQ(out.reconnects, 0);
  expectPosesOnceEach(s.journalled(), 2);
  // The servo's first move was never executed: the robot stands where the third pose's move
  // ended (the planned pose aimed at the predicted spot, checked against the limits), and
  // nothing moves it.
  const Joints at_rest = controller.commandedJoints();
  expectAt(at_rest, move_end);
  for (int j = 0; j < kJointCount; ++j) EXPECT_NEAR(at_rest[j], s.plan[2].q_deg[j], 6.0);
  EXPECT_TRUE(s.rig.cell.world().robot.withinLimits(at_rest, 1.0));
}

TEST(SessionFaults, BoardUnpluggedMidServoIsReopenedOnceReplugged) {
  Session s(25);
  HookedPsd psd(s.rig.psd);
  int reopen_calls = 0;
  bool unplugged = false;
  s.settings.reopen_sensor = [&] {
    // The first attempt finds no board; by the second the technician has plugged it back in.
    if (++reopen_calls == 2) s.rig.cell.board().replug();
    s.rig.daq.reopen();
  };
  const RunOutcome out = s.run(s.rig.client, psd, [&](CalibrationRun& run) {
    run.on_phase = [&](int i, RunPhase phase) {
      if (i == 3 && phase == RunPhase::kServoing && !unplugged) {
        // Unplugged on the servo's second reading of pose 4.
        const int first = psd.reads + 2;
        psd.before_read = [&, first](int n) {
          if (n != first) return;
          s.rig.cell.board().unplug();
          unplugged = true;
        };
      }
    };
  });
  ASSERT_EQ(out.state, RunState::kCompleted) << out.message;
  EXPECT_TRUE(unplugged);
  EXPECT_EQ(reopen_calls, 2);
  EXPECT_EQ(out.reopens, 1);
  expectPosesOnceEach(s.journalled(), s.plan.size());
  expectWithinThreeSigma(out, s.rig.cell.world());
}

TEST(SessionFaults, BoardThatNeverComesBackFaultsNamingThePose) {
  Session s(25);
  SimController& controller = s.rig.cell.controller();
  s.settings.reopen_sensor = [&] { s.rig.daq.reopen(); };
  s.settings.recovery_attempts = 3;
  const double backoff_s = s.settings.recovery_backoff_s;
  double unplugged_s = 0;
  const RunOutcome out = s.run(s.rig.client, s.rig.psd, [&](CalibrationRun& run) {
    run.on_phase = [&](int i, RunPhase phase) {
      if (i == 1 && phase == RunPhase::kServoing) {
        s.rig.cell.board().unplug();
        unplugged_s = s.rig.cell.nowS();
      }
    };
  });
  EXPECT_EQ(out.state, RunState::kFaulted);
  EXPECT_NE(out.message.find("pose 2 of 8"), std::string::npos) << out.message;
  EXPECT_NE(out.message.find("reopening the board failed 3 times"), std::string::npos)
      << out.message;
  expectPosesOnceEach(s.journalled(), 1);
  // Two back-offs between three attempts, on the cell's clock.
  EXPECT_NEAR(s.rig.cell.nowS() - unplugged_s, 2 * backoff_s, 0.5);
  const Joints at_rest = controller.commandedJoints();
  expectAt(at_rest, s.plan[1].q_deg);
}

// A link that answers each request only after 30 s spends the servo's time: pose 1 fails on
// time, but the link is named as the cause, and the pose is not offered to skip.
TEST(SessionFaults, ASlowLinkIsNamedAsTheCauseOfAPoseThatFailedOnTime) {
  Session s(24);
  SlowLink link(s.rig.client, s.rig.cell);
  link.delay_s = 30;
  const RunOutcome out = s.run(link, s.rig.psd);
  EXPECT_EQ(out.state, RunState::kFaulted);
  EXPECT_NE(out.message.find("pose 1 of 8"), std::string::npos) << out.message;
  EXPECT_NE(out.message.find("the controller link is slow (the fastest of 3 pings took 30.00 s"),
            std::string::npos)
      << out.message;
  EXPECT_NE(out.message.find("the link is at fault, not the pose"), std::string::npos)
      << out.message;
  EXPECT_FALSE(out.pose_at_fault);
  EXPECT_EQ(out.stopped_at, 0);
  EXPECT_TRUE(s.journalled().empty());
}

// The same link at a healthy speed: the session is not disturbed by the probe.
TEST(SessionFaults, AHealthyLinkLeavesAPoseWhoseSpotIsNeverFoundAtFault) {
  Session s(12, Taught::k100MmOff);
  s.settings.servo.search_radius_mm = 10;
  SlowLink link(s.rig.client, s.rig.cell);
  link.delay_s = 0.002;
  const RunOutcome out = s.run(link, s.rig.psd);
  EXPECT_EQ(out.state, RunState::kFaulted);
  EXPECT_NE(out.message.find("spot not found"), std::string::npos) << out.message;
  EXPECT_EQ(out.message.find("link"), std::string::npos) << out.message;
  EXPECT_TRUE(out.pose_at_fault);
}

// The session believes the PSD is 100 mm from where it is: no spot anywhere near the plan.
TEST(SessionFaults, SpotNeverFoundFaultsNamingThePoseWithTheRobotBackAtThePlannedPose) {
  Session s(12, Taught::k100MmOff);
  s.settings.servo.search_radius_mm = 10;
  RecordingLink link(s.rig.client);
  const RunOutcome out = s.run(link, s.rig.psd);
  EXPECT_EQ(out.state, RunState::kFaulted);
  EXPECT_NE(out.message.find("pose 1 of 8"), std::string::npos) << out.message;
  EXPECT_NE(out.message.find("spot not found"), std::string::npos) << out.message;
  EXPECT_TRUE(s.journalled().empty());
  // "Safe" is the planned pose: checked against the limits less the margin before the session,
  // reached by the planned move. The search walked away from it in small checked steps and back.
  const Joints& planned = s.plan[0].q_deg;
  const Robot& robot = s.rig.cell.world().robot;
  EXPECT_TRUE(robot.withinLimits(planned, s.settings.servo.limit_margin_deg));
  ASSERT_GE(link.moves.size(), 3u);  // the planned move, the search, the walk back
  expectAt(link.moves.front(), planned);
  expectAt(link.moves.back(), planned);
  for (std::size_t k = 1; k < link.moves.size(); ++k) {
    EXPECT_TRUE(robot.withinLimits(link.moves[k], s.settings.servo.limit_margin_deg));
    for (int j = 0; j < kJointCount; ++j)
      EXPECT_LE(std::abs(link.moves[k][j] - link.moves[k - 1][j]),
                s.settings.servo.max_step_deg + 1e-9);
  }
  expectAt(s.rig.cell.controller().commandedJoints(), planned);
}

// Forwards to the real chain and keeps every reading with the joints last commanded.
class RecordingPsd final : public PsdReader {
 public:
  RecordingPsd(PsdReader& inner, const RecordingLink& link) : inner_(inner), link_(link) {}
  PsdReading read() override {
    readings.push_back(inner_.read());
    joints.push_back(link_.moves.back());
    return readings.back();
  }
  std::vector<PsdReading> readings;
  std::vector<Joints> joints;

 private:
  PsdReader& inner_;
  const RecordingLink& link_;
};

// The servo's latched fault keeps its last 32 samples; they reach faults.jsonl, durably, beside a
// journal that stays as it was (empty here, so a resume measures pose 1 again).
TEST(SessionFaults, ALatchedFaultsRecentSamplesAreWrittenToFaultsJsonl) {
  Session s(12, Taught::k100MmOff);
  s.settings.servo.search_radius_mm = 20;  // ~80 points, none near the spot 100 mm away
  RecordingLink link(s.rig.client);
  RecordingPsd psd(s.rig.psd, link);
  const RunOutcome out = s.run(link, psd);
  ASSERT_EQ(out.state, RunState::kFaulted);
  EXPECT_TRUE(s.journalled().empty());

  const std::vector<FaultRecord> faults = readFaults(s.dir.path + "/faults.jsonl");
  ASSERT_EQ(faults.size(), 1u);
  const FaultRecord& f = faults.front();
  EXPECT_EQ(f.plan_index, 0);
  EXPECT_FALSE(f.remeasure);
  EXPECT_EQ(f.status, "spot not found");
  EXPECT_NE(out.message.find(f.message), std::string::npos) << f.message;
  EXPECT_GT(f.recorded_ns, 0);
  // The fault's samples are the run's last 32 readings, oldest first, each with the joints
  // commanded when it was taken, read back to the bit.
  ASSERT_GT(psd.readings.size(), servo::kFaultHistory);
  ASSERT_EQ(f.samples.size(), servo::kFaultHistory);
  const std::size_t first = psd.readings.size() - servo::kFaultHistory;
  for (std::size_t k = 0; k < f.samples.size(); ++k) {
    const servo::ServoSample& got = f.samples[k];
    const PsdReading& read = psd.readings[first + k];
    EXPECT_EQ(got.time_s, read.time_s) << k;
    EXPECT_EQ(got.q_deg, psd.joints[first + k]) << k;
    EXPECT_EQ(got.reading.spot, read.spot) << k;
    EXPECT_EQ(got.reading.sum_v, read.sum_v) << k;
    EXPECT_EQ(got.reading.spot_present, read.spot_present) << k;
    EXPECT_EQ(got.reading.in_valid_zone, read.in_valid_zone) << k;
  }
}

// Abort while the servo searches a spot it cannot find (a search of up to 3000 points): no
// further move is sent once the flag is set.
TEST(SessionFaults, AbortDuringALongSearchStopsWithinOneServoMove) {
  Session s(12, Taught::k100MmOff);
  RecordingLink link(s.rig.client);
  HookedPsd psd(s.rig.psd);
  std::size_t moves_at_abort = 0;
  psd.before_read = [&](int n) {
    if (n != 40) return;
    s.abort = true;
    moves_at_abort = link.moves.size();
  };
  const RunOutcome out = s.run(link, psd);
  EXPECT_EQ(out.state, RunState::kAborted);
  EXPECT_NE(out.message.find("pose 1 of 8"), std::string::npos) << out.message;
  ASSERT_GT(moves_at_abort, 0u);
  EXPECT_LE(link.moves.size(), moves_at_abort + 1);
  EXPECT_TRUE(s.journalled().empty());
  expectAt(s.rig.cell.controller().commandedJoints(), link.moves.back());
}

// Abort set at each phase of the third pose (and before the solve): the run stops as aborted with
// exactly the poses recorded before, and no move follows the abort beyond the one under way.
TEST(SessionFaults, AbortInEveryPhase) {
  for (RunPhase at :
       {RunPhase::kMoving, RunPhase::kServoing, RunPhase::kRecording, RunPhase::kSolving}) {
    SCOPED_TRACE(static_cast<int>(at));
    Session s(26);
    RecordingLink link(s.rig.client);
    std::size_t moves_at_abort = 0;
    const RunOutcome out = s.run(link, s.rig.psd, [&](CalibrationRun& run) {
      run.on_phase = [&](int i, RunPhase phase) {
        if (phase != at || (at != RunPhase::kSolving && i != 2)) return;
        s.abort = true;
        moves_at_abort = link.moves.size();
      };
    });
    EXPECT_EQ(out.state, RunState::kAborted) << out.message;
    EXPECT_FALSE(out.report.has_value());
    // kMoving: the planned move is the one under way; afterwards nothing.
    EXPECT_LE(link.moves.size(), moves_at_abort + (at == RunPhase::kMoving ? 1 : 0));
    const std::size_t recorded = at == RunPhase::kSolving     ? s.plan.size()
                                 : at == RunPhase::kRecording ? 3
                                                              : 2;
    expectPosesOnceEach(s.journalled(), recorded);
  }
}

TEST(SessionFaults, JournalKeepsTheServoPathAndTheBreakdownAddsUp) {
  Session s(27);
  double last_recorded_s = 0;
  std::vector<double> pose_cell_s;
  const auto unix_ns = [] {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
  };
  const std::int64_t started_ns = unix_ns();
  const RunOutcome out = s.run(s.rig.client, s.rig.psd, [&](CalibrationRun& run) {
    run.on_phase = [&](int, RunPhase phase) {
      if (phase == RunPhase::kMoving) last_recorded_s = s.rig.cell.nowS();
    };
    run.on_pose = [&](const PoseRecord&) {
      pose_cell_s.push_back(s.rig.cell.nowS() - last_recorded_s);
    };
  });
  ASSERT_EQ(out.state, RunState::kCompleted) << out.message;
  const std::int64_t ended_ns = unix_ns();
  const std::vector<PoseRecord> records = s.journalled();
  ASSERT_EQ(records.size(), s.plan.size());
  std::int64_t previous_ns = started_ns;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const PoseRecord& r = records[i];
    // Timestamps are wall time since the Unix epoch, in the order things happened.
    EXPECT_LE(previous_ns, r.move_started_ns);
    EXPECT_LE(r.move_started_ns, r.recorded_ns);
    EXPECT_LE(r.recorded_ns, ended_ns);
    previous_ns = r.recorded_ns;
    const ServoStats& st = r.servo;
    EXPECT_NEAR(st.move_s + st.acquisition_s + st.servo_s + st.settle_s, pose_cell_s[i], 1e-6);
    // Settling: at least once at the start and once for the settled pair, 0.2 s each.
    EXPECT_GE(st.settle_s, 0.2 - 1e-9);
    EXPECT_NEAR(std::fmod(st.settle_s + 1e-9, 0.2), 0, 1e-6);
    ASSERT_FALSE(r.servo_path.empty()) << "pose " << i;
    EXPECT_LE(r.servo_path.size(), servo::kPathCapacity);
    for (std::size_t k = 1; k < r.servo_path.size(); ++k)
      EXPECT_GT(r.servo_path[k].t_s, r.servo_path[k - 1].t_s);
    // The last point is the recorded reading.
    EXPECT_DOUBLE_EQ(r.servo_path.back().spot.u_mm, r.reading.spot.u_mm);
    EXPECT_DOUBLE_EQ(r.servo_path.back().spot.v_mm, r.reading.spot.v_mm);
  }
}

}  // namespace
}  // namespace zerocal
