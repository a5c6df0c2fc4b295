// How a calibration run classifies its failures, against strict mocks of the seams (the controller
// link, the PSD reader, the cell clock) and of the recovery hooks: every call the run makes is
// expected, in order, and any other call fails the test. What is retried after which hook, what
// ends the run at once, which fault is the pose's own, what the clock is asked to wait.
// session_faults_test.cpp runs some of the same paths on the whole simulated cell, judged by the
// result; these pin the calls down: a refused move never sent again, the hook called exactly
// once, the pose redone from its planned move.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <string>
#include <vector>

#include "stored_plan.h"
#include "temp_dir.h"
#include "zerocal/calib/experiment.h"
#include "zerocal/cell/link_error.h"
#include "zerocal/session/calibration_run.h"

namespace zerocal {
namespace {

using ::testing::_;
using ::testing::AnyNumber;
using ::testing::HasSubstr;
using ::testing::InSequence;
using ::testing::MockFunction;
using ::testing::Return;
using ::testing::StrictMock;
using ::testing::Throw;

class MockLink : public ControllerLink {
 public:
  MOCK_METHOD(void, ping, (), (override));
  MOCK_METHOD(RobotInfo, robotInfo, (), (override));
  MOCK_METHOD(Joints, readJoints, (), (override));
  MOCK_METHOD(void, moveJoints, (const Joints& target_deg), (override));
  MOCK_METHOD(TcpPose, readPose, (), (override));
  MOCK_METHOD(void, moveLinear, (const TcpPose& target), (override));
};

class MockPsd : public PsdReader {
 public:
  MOCK_METHOD(PsdReading, read, (), (override));
};

class MockClock : public CellClock {
 public:
  MOCK_METHOD(double, nowS, (), (noexcept, override));
  MOCK_METHOD(void, waitS, (double seconds), (noexcept, override));
};

LinkError failure(LinkError::Kind kind) {
  return LinkError(kind, std::string(linkErrorKindName(kind)) + " failure");
}

// The spot on the detector, in the map's zone, `u_mm` from its centre.
PsdReading spotAt(double u_mm) {
  PsdReading r;
  r.spot.u_mm = u_mm;
  r.spot_present = r.in_valid_zone = true;
  return r;
}

PsdReading dark() { return PsdReading{}; }

class RunClassification : public ::testing::Test {
 protected:
  RunClassification() {
    // Two poses of the optimal plan for the paper's cell: every run here stops before the solve
    // (which would need six).
    const std::vector<Pose> stored = testing::storedPlan("table2-8");
    plan.assign(stored.begin(), stored.begin() + 2);
    // The daemon's servo stops in the zone on two agreeing readings; stopping at the centre, on
    // the first centred one, a measured pose is exactly a move, a joint read-back and one
    // reading. No settling: waitS() is called by the recovery's back-off alone.
    settings.servo.stop = servo::ServoStop::kCentre;
    settings.servo.settle_s = 0;
    settings.reconnect_link = reconnect.AsStdFunction();
    settings.reopen_sensor = reopen.AsStdFunction();
    // Durations are not judged here; every call of waitS() is.
    EXPECT_CALL(clock, nowS()).Times(AnyNumber()).WillRepeatedly(Return(0.0));
  }

  // With `stop_after_a_pose`, the first recorded pose ends the run (aborted before the next):
  // what follows a recovery is seen without measuring the rest of the plan.
  RunOutcome run(bool stop_after_a_pose = true) {
    Journal journal(dir.path + "/journal.jsonl");
    CalibrationRun r(scenario.cell, scenario.truth.target_mm, plan, settings, journal);
    if (stop_after_a_pose) r.on_pose = [this](const PoseRecord&) { abort = true; };
    return r.run(link, psd, clock, abort);
  }

  std::vector<PoseRecord> journalled() const {
    return readJournal(dir.path + "/journal.jsonl").records;
  }

  // The calls of a pose measured at once: its planned move, the servo's read-back of the joints,
  // one centred reading.
  void expectMeasured(const Joints& planned) {
    EXPECT_CALL(link, moveJoints(planned));
    EXPECT_CALL(link, readJoints()).WillOnce(Return(planned));
    EXPECT_CALL(psd, read()).WillOnce(Return(spotAt(0)));
  }

  // The planned move and the read-back, after which the servo reads the PSD.
  void expectAtPose(const Joints& planned) {
    EXPECT_CALL(link, moveJoints(planned));
    EXPECT_CALL(link, readJoints()).WillOnce(Return(planned));
  }

  // The pose recorded after `reconnects` and `reopens` recoveries, and the run stopped (run()).
  void expectRecordedAfter(const RunOutcome& out, int reconnects, int reopens) {
    EXPECT_EQ(out.state, RunState::kAborted) << out.message;
    EXPECT_EQ(out.reconnects, reconnects);
    EXPECT_EQ(out.reopens, reopens);
    const std::vector<PoseRecord> records = journalled();
    ASSERT_EQ(records.size(), 1u);
    EXPECT_EQ(records[0].joints_deg, plan[0].q_deg);
  }

  void expectFaultedAt(const RunOutcome& out, int pose, bool pose_at_fault) {
    EXPECT_EQ(out.state, RunState::kFaulted);
    EXPECT_EQ(out.stopped_at, pose);
    EXPECT_EQ(out.pose_at_fault, pose_at_fault);
    EXPECT_THAT(out.message, HasSubstr("pose " + std::to_string(pose + 1) + " of 2"));
    EXPECT_FALSE(out.report.has_value());
  }

  const Table2Scenario scenario = table2Scenario();
  std::vector<Pose> plan;
  RunSettings settings;
  testing::TempDir dir{"zerocal-classification"};
  StrictMock<MockLink> link;
  StrictMock<MockPsd> psd;
  StrictMock<MockClock> clock;
  StrictMock<MockFunction<void()>> reconnect, reopen;
  std::atomic<bool> abort{false};
};

TEST_F(RunClassification, ARefusedMoveFaultsAtOnceAsThePosesOwnAndIsNeverSentAgain) {
  EXPECT_CALL(link, moveJoints(plan[0].q_deg)).WillOnce(Throw(failure(LinkError::Kind::kRefused)));
  const RunOutcome out = run();
  expectFaultedAt(out, 0, true);
  EXPECT_THAT(out.message, HasSubstr("move failed: refused failure"));
  EXPECT_EQ(out.reconnects, 0);
  EXPECT_TRUE(journalled().empty());
}

TEST_F(RunClassification, AFatalMoveFaultsAtOnceWithoutAHookAndIsNotThePosesOwn) {
  EXPECT_CALL(link, moveJoints(plan[0].q_deg)).WillOnce(Throw(failure(LinkError::Kind::kFatal)));
  const RunOutcome out = run();
  expectFaultedAt(out, 0, false);
  EXPECT_THAT(out.message, HasSubstr("fatal failure"));
}

TEST_F(RunClassification, ATransientMoveReconnectsOnceThenRedoesThePoseFromItsPlannedMove) {
  {
    InSequence order;
    EXPECT_CALL(link, moveJoints(plan[0].q_deg))
        .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reconnect, Call());
    expectMeasured(plan[0].q_deg);
  }
  expectRecordedAfter(run(), 1, 0);
}

TEST_F(RunClassification, ATransientMoveWithoutAReconnectHookFaults) {
  settings.reconnect_link = nullptr;
  EXPECT_CALL(link, moveJoints(plan[0].q_deg))
      .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
  const RunOutcome out = run();
  expectFaultedAt(out, 0, false);
  EXPECT_EQ(out.reconnects, 0);
}

// The servo latches the link's failure (its joint read-back here); the run reconnects and starts
// the pose again from the planned move, not from where the servo was.
TEST_F(RunClassification, ALinkFailureInTheServoReconnectsAndRedoesThePose) {
  {
    InSequence order;
    EXPECT_CALL(link, moveJoints(plan[0].q_deg));
    EXPECT_CALL(link, readJoints()).WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reconnect, Call());
    expectMeasured(plan[0].q_deg);
  }
  expectRecordedAfter(run(), 1, 0);
}

TEST_F(RunClassification, ATransientSensorFailureReopensTheBoardAndRedoesThePose) {
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reopen, Call());
    expectMeasured(plan[0].q_deg);
  }
  expectRecordedAfter(run(), 0, 1);
}

TEST_F(RunClassification, AFatalSensorFailureFaultsWithoutReopening) {
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Throw(failure(LinkError::Kind::kFatal)));
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, false);
  EXPECT_THAT(out.message, HasSubstr("sensor error"));
}

// Three calls of the hook, the back-off waited on the cell's clock between them (not after the
// last), then the run gives up with the last problem; nothing moves after the failed move.
TEST_F(RunClassification, RecoveryThatKeepsFailingGivesUpAfterItsAttemptsWithBackOffBetween) {
  settings.recovery_attempts = 3;
  settings.recovery_backoff_s = 2.5;
  {
    InSequence order;
    EXPECT_CALL(link, moveJoints(plan[0].q_deg))
        .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reconnect, Call()).WillOnce(Throw(Error("attempt 1 refused")));
    EXPECT_CALL(clock, waitS(2.5));
    EXPECT_CALL(reconnect, Call()).WillOnce(Throw(Error("attempt 2 refused")));
    EXPECT_CALL(clock, waitS(2.5));
    EXPECT_CALL(reconnect, Call()).WillOnce(Throw(Error("attempt 3 refused")));
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, false);
  EXPECT_THAT(out.message, HasSubstr("reconnecting failed 3 times: attempt 3 refused"));
  EXPECT_EQ(out.reconnects, 0);
}

// Two poses: the first is recorded after one recovery; the second fails every time and is given
// up after recoveries_per_pose recoveries of its own (the first pose's does not count).
TEST_F(RunClassification, RecoveriesPerPoseBoundTheRetriesOfEachPose) {
  settings.recoveries_per_pose = 2;
  {
    InSequence order;
    EXPECT_CALL(link, moveJoints(plan[0].q_deg))
        .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reconnect, Call());
    expectMeasured(plan[0].q_deg);
    for (int recovery = 1; recovery <= 2; ++recovery) {
      EXPECT_CALL(link, moveJoints(plan[1].q_deg))
          .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
      EXPECT_CALL(reconnect, Call());
    }
    EXPECT_CALL(link, moveJoints(plan[1].q_deg))
        .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
  }
  const RunOutcome out = run(false);
  expectFaultedAt(out, 1, false);
  EXPECT_THAT(out.message, HasSubstr("2 recoveries already on this pose"));
  EXPECT_EQ(out.reconnects, 3);
  EXPECT_EQ(journalled().size(), 1u);
}

TEST_F(RunClassification, AnAbortDuringRecoveryEndsTheRunAbortedWithoutAnotherAttempt) {
  {
    InSequence order;
    EXPECT_CALL(link, moveJoints(plan[0].q_deg))
        .WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reconnect, Call()).WillOnce([this] {
      abort = true;  // the technician gives up on the cable
      throw Error("still down");
    });
    EXPECT_CALL(clock, waitS(settings.recovery_backoff_s));
  }
  const RunOutcome out = run();
  EXPECT_EQ(out.state, RunState::kAborted);
  EXPECT_THAT(out.message, HasSubstr("aborted while recovering pose 1 of 2"));
  EXPECT_EQ(out.reconnects, 0);
  EXPECT_TRUE(journalled().empty());
}

// The servo's own failures are the pose's: measuring it again would fail again, so no hook is
// called and nothing is retried.
TEST_F(RunClassification, ASpotNeverFoundIsThePosesOwnWithTheRobotWalkedBackToIt) {
  settings.servo.search_radius_mm = 0;  // no search: the planned pose alone is tried
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Return(dark()));
    EXPECT_CALL(link, moveJoints(plan[0].q_deg));  // back at the planned pose
    EXPECT_CALL(link, ping());                     // the link answers at once: sound
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, true);
  EXPECT_THAT(out.message, HasSubstr("spot not found"));
}

// The same spot not found, but the link fails when asked: the link is at fault. It is made again
// and the pose done again from its planned move.
TEST_F(RunClassification, ASpotNotFoundWhenTheLinkFailsIsTheLinksAndThePoseIsDoneAgain) {
  settings.servo.search_radius_mm = 0;
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Return(dark()));
    EXPECT_CALL(link, moveJoints(plan[0].q_deg));
    EXPECT_CALL(link, ping()).WillOnce(Throw(failure(LinkError::Kind::kTransient)));
    EXPECT_CALL(reconnect, Call());
    expectMeasured(plan[0].q_deg);
  }
  const RunOutcome out = run();
  expectRecordedAfter(out, 1, 0);
}

// A link whose every answer takes 0.25 s of cell time: the fault names it, and the pose is not
// the one at fault (no skip is offered for it).
TEST_F(RunClassification, ASpotNotFoundOverASlowLinkIsTheLinksAndNotThePoses) {
  settings.servo.search_radius_mm = 0;
  double now = 0;
  EXPECT_CALL(clock, nowS()).WillRepeatedly([&now]() noexcept { return now += 0.25; });
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Return(dark()));
    EXPECT_CALL(link, moveJoints(plan[0].q_deg));
    EXPECT_CALL(link, ping()).Times(3);
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, false);
  EXPECT_THAT(out.message, HasSubstr("spot not found"));
  EXPECT_THAT(out.message, HasSubstr("but the controller link is slow (the fastest of 3 pings "
                                     "took 0.25 s"));
  EXPECT_THAT(out.message, HasSubstr("the link is at fault, not the pose"));
}

TEST_F(RunClassification, ASpotLostDuringTheServoIsThePosesOwn) {
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Return(spotAt(1.0)));
    EXPECT_CALL(link, moveJoints(_));  // the first step towards the centre
    EXPECT_CALL(psd, read()).WillOnce(Return(dark()));
    EXPECT_CALL(link, ping());
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, true);
  EXPECT_THAT(out.message, HasSubstr("spot lost"));
}

TEST_F(RunClassification, AServoThatDoesNotConvergeIsThePosesOwn) {
  settings.servo.max_iterations = 1;
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Return(spotAt(1.0)));
    EXPECT_CALL(link, moveJoints(_));
    EXPECT_CALL(psd, read()).WillOnce(Return(spotAt(1.0)));  // the spot did not move
    EXPECT_CALL(link, ping());
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, true);
  EXPECT_THAT(out.message, HasSubstr("not converged"));
}

// A planned pose 0.2 deg inside joint 1's limit: with the 1 deg margin the servo keeps, its first
// step is refused before it is sent.
TEST_F(RunClassification, AServoStepBeyondTheLimitsIsThePosesOwnAndIsNotSent) {
  plan[0].q_deg[0] = scenario.cell.robot.limits[0].upper_deg - 0.2;
  {
    InSequence order;
    expectAtPose(plan[0].q_deg);
    EXPECT_CALL(psd, read()).WillOnce(Return(spotAt(0.1)));
  }
  const RunOutcome out = run();
  expectFaultedAt(out, 0, true);
  EXPECT_THAT(out.message, HasSubstr("servo limit"));
}

}  // namespace
}  // namespace zerocal
