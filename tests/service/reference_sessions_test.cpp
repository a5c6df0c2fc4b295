// A robot's life through the session manager on the simulated cell: a reference at known-good
// zeros, a check that passes, a motor replaced (one joint's true zero moved), a check that names
// the joint, a restore that measures the change, its apply verified against the reference, and
// what is refused on the way.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "stored_plan_request.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/record/sqlite_record.h"
#include "zerocal/report/session_report.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/sim_backend.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal::service {
namespace {

struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-reference-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

// The ideal world of seed 5 on its stored plan (no seconds of planning), the sessions' noise the
// simulated repeatability at the detector.
ManagerSettings settingsIn(const std::string& dir) {
  ManagerSettings s;
  s.session.data_dir = dir;
  s.run.servo.stop = servo::ServoStop::kZone;
  s.session.noise_mm = 0.020;
  s.session.plan = PlanKind::kFile;
  s.session.plan_file = testing::storedPlanPath("ideal-5");
  return s;
}

StartRequest kindOf(SessionManager& manager, SessionKind kind) {
  StartRequest r = manager.defaultRequest();
  r.kind = kind;
  return r;
}

std::string refusalOf(const std::function<void()>& call) {
  try {
    call();
  } catch (const Refused& e) {
    return e.code();
  }
  return "";
}

// A motor replaced: joint's true zero moves by `deg`, its cal_offset with it (the technician
// synchronised the new motor by its marks).
void replaceMotor(sim::SimBackend& backend, const Robot& robot, int joint, double deg) {
  SimController& controller = backend.cell().controller();
  const double k = robot.transmission[joint - 1];
  double rad = controller.calOffsets()[joint - 1] + k * deg * kDegToRad;
  rad = std::fmod(std::fmod(rad, 2 * kPi) + 2 * kPi, 2 * kPi);
  controller.writeCalOffset(joint, rad);
}

TEST(ReferenceSessions, AReferenceACheckAMotorReplacedARestoreAppliedAndVerified) {
  const TempDir dir;
  sim::SimBackend backend(sim::seededCellOptions(5, WorldKind::kIdeal));
  const Robot robot = backend.knowledge().cell.robot;
  // As the daemon keeps them: the robot's record, and each session's report with its trend.
  record::SqliteRecord record(dir.path + "/" + record::kRecordFileName);
  ManagerSettings settings = settingsIn(dir.path);
  settings.record = &record;
  settings.write_reports = [](const std::string& session_dir,
                              const std::vector<record::HistoryEntry>& history) {
    report::writeSessionReport(session_dir, history);
  };
  SessionManager manager(backend, settings);

  // Nothing to compare with yet: the daemon suggests a reference.
  EXPECT_EQ(refusalOf([&] { manager.start(kindOf(manager, SessionKind::kCheck)); }),
            "no_reference");
  EXPECT_NE(manager.status().suggestion.find("--kind reference"), std::string::npos)
      << manager.status().suggestion;

  const std::string reference = manager.start(kindOf(manager, SessionKind::kReference));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile taken = manager.result(reference);
  EXPECT_EQ(taken.kind, SessionKind::kReference);
  EXPECT_TRUE(taken.report.verdict.usable)
      << ::testing::PrintToString(taken.report.verdict.reasons);
  // With one, a check against it.
  EXPECT_NE(manager.status().suggestion.find("reference " + reference +
                                             ": `zerocal start --kind "
                                             "check`"),
            std::string::npos)
      << manager.status().suggestion;
  // A reference writes nothing.
  EXPECT_EQ(refusalOf([&] { manager.apply({reference, true}); }), "not_usable");

  // The robot unchanged: a check of a few of the reference's poses passes.
  const std::string same = manager.start(kindOf(manager, SessionKind::kCheck));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile passed = manager.result(same);
  EXPECT_EQ(passed.kind, SessionKind::kCheck);
  EXPECT_EQ(passed.reference, reference);
  ASSERT_TRUE(passed.check);
  EXPECT_EQ(passed.check->outcome, CheckJudgement::Outcome::kPass) << passed.check->summary;
  EXPECT_LT(passed.report.pose_count, taken.report.pose_count);
  EXPECT_EQ(refusalOf([&] { manager.apply({same, true}); }), "not_usable");

  // Joint 3's motor replaced: its zero moved by 0.3 deg. A check names it, a restore measures it.
  replaceMotor(backend, robot, 3, 0.3);
  const double moved_deg = backend.cell().controller().zeroShiftDeg()[2];
  ASSERT_NEAR(moved_deg, 0.3, 1e-4);
  const std::string named = manager.start(kindOf(manager, SessionKind::kCheck));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile changed = manager.result(named);
  ASSERT_TRUE(changed.check);
  EXPECT_EQ(changed.check->outcome, CheckJudgement::Outcome::kChanged) << changed.check->summary;
  EXPECT_EQ(changed.check->joints, std::vector<int>{3});
  // Against the check before it, that is a drift of joint 3 alone.
  ASSERT_EQ(changed.drift.size(), 1u);
  EXPECT_EQ(changed.drift[0].joint, 3);
  EXPECT_EQ(changed.drift[0].since, same);
  EXPECT_TRUE(passed.drift.empty());

  const std::string restore = manager.start(kindOf(manager, SessionKind::kRestore));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile found = manager.result(restore);
  EXPECT_EQ(found.kind, SessionKind::kRestore);
  EXPECT_TRUE(found.drift.empty());  // the zero as the check before it found it
  EXPECT_TRUE(found.report.verdict.usable)
      << ::testing::PrintToString(found.report.verdict.reasons);
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& p = found.report.parameters[k];
    EXPECT_NEAR(p.value, k == 1 ? moved_deg : 0.0, 4 * p.sigma) << p.name;
    EXPECT_LT(p.sigma, 0.003) << p.name;
  }

  // Applied: the zeros are the reference's again, the verification a check against it.
  EXPECT_EQ(manager.apply({restore, true}), restore);
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.apply.rfind("session " + restore + " verified", 0), 0u) << end.apply;
  // Within three of the restore's sigmas of the reference's zero: what the restore claims.
  const double restored_sigma = found.report.parameters[1].sigma;
  std::printf("joint 3's zero after the apply: %+.4f deg from the reference's, sigma %.4f\n",
              backend.cell().controller().zeroShiftDeg()[2], restored_sigma);
  EXPECT_NEAR(backend.cell().controller().zeroShiftDeg()[2], 0.0, 3 * restored_sigma);
  const std::vector<SessionInfo> sessions = manager.sessions();
  ASSERT_FALSE(sessions.empty());
  const SessionInfo& verification = sessions.back();
  EXPECT_EQ(verification.kind, SessionKind::kVerification);
  EXPECT_EQ(verification.verifies, restore);
  EXPECT_EQ(manager.result(verification.id).reference, reference);
  EXPECT_TRUE(manager.result(verification.id).drift.empty());
  // A check after the apply: against the verification, nothing moved.
  const std::string after = manager.start(kindOf(manager, SessionKind::kCheck));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile back = manager.result(after);
  ASSERT_TRUE(back.check);
  EXPECT_EQ(back.check->outcome, CheckJudgement::Outcome::kPass) << back.check->summary;
  EXPECT_TRUE(back.drift.empty());

  // Its report shows each zero's change since the reference over the robot's life: a point for
  // each of the five sessions compared with it (two checks, the restore, its verification, this
  // check), this one marked, and the apply as a line.
  std::ifstream in(dir.path + "/" + after + "/report.html");
  std::stringstream text;
  text << in.rdbuf();
  const std::string html = text.str();
  ASSERT_NE(html.find(report::escapeHtml("Each zero's change since reference " + reference +
                                         ", as the 5 sessions compared with it in the record "
                                         "found it")),
            std::string::npos);
  std::string joint3 = html.substr(html.find("id=\"trend-delta3\""));
  joint3 = joint3.substr(0, joint3.find("</svg>"));
  const auto count = [&](const std::string& what) {
    int n = 0;
    for (std::size_t at = joint3.find(what); at != std::string::npos;
         at = joint3.find(what, at + 1))
      ++n;
    return n;
  };
  EXPECT_EQ(count("class=\"point"), 5);
  EXPECT_EQ(count("class=\"point current\""), 1);
  EXPECT_EQ(count("class=\"change\""), 1) << "the restore's apply";
  // The reference's own report has no trend: nothing compared with it yet when it was written.
  std::ifstream reference_report(dir.path + "/" + reference + "/report.html");
  std::stringstream reference_text;
  reference_text << reference_report.rdbuf();
  EXPECT_EQ(reference_text.str().find("zeros over time"), std::string::npos);
}

// A check is meant to take half a minute: a pose it leaves out (stray light at it) is measured
// again only when the check cannot decide without it.
TEST(ReferenceSessions, ACheckThatDecidesWithoutADisturbedPoseDoesNotMeasureItAgain) {
  const TempDir dir;
  Joints disturbed{};
  {
    sim::SimBackend backend(sim::seededCellOptions(5, WorldKind::kIdeal));
    SessionManager manager(backend, settingsIn(dir.path));
    manager.start(kindOf(manager, SessionKind::kReference));
    ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
    const Plan check = manager.preview(kindOf(manager, SessionKind::kCheck));
    ASSERT_GE(check.poses.size(), 4u);
    disturbed = check.poses[1].q_deg;
  }
  // The same cell, the same data folder: stray light strikes the check's second pose.
  sim::SimulatedCellOptions cell = sim::seededCellOptions(5, WorldKind::kIdeal);
  cell.world.gross.forced_at_deg = disturbed;
  cell.world.gross.forced_kind = GrossErrors::Kind::kStrayLight;
  sim::SimBackend backend(cell);
  SessionManager manager(backend, settingsIn(dir.path));
  const std::string id = manager.start(kindOf(manager, SessionKind::kCheck));
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile checked = manager.result(id);
  ASSERT_TRUE(checked.check);
  EXPECT_EQ(checked.check->outcome, CheckJudgement::Outcome::kPass) << checked.check->summary;
  // The pose was left out and named, and not measured again.
  ASSERT_EQ(checked.report.suspect_poses.size(), 1u);
  EXPECT_EQ(checked.report.suspect_poses[0].pose, 2);
  EXPECT_FALSE(checked.report.poses[1].used);
  ASSERT_TRUE(checked.remeasured);
  EXPECT_TRUE(checked.remeasured->empty());
  EXPECT_EQ(checked.report.poses_used, static_cast<int>(checked.report.poses.size()) - 1);
}

TEST(ReferenceSessions, ACheckAgainstWhatIsNoReferenceIsRefusedSayingWhy) {
  const TempDir dir;
  sim::SimBackend backend(sim::seededCellOptions(5, WorldKind::kIdeal));
  SessionManager manager(backend, settingsIn(dir.path));
  const std::string calibration = manager.start(manager.defaultRequest());
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  StartRequest check = kindOf(manager, SessionKind::kCheck);
  check.reference = calibration;
  EXPECT_EQ(refusalOf([&] { manager.start(check); }), "not_a_reference");
  check.reference = "20991231T000000Z";
  EXPECT_EQ(refusalOf([&] { manager.start(check); }), "not_found");
  check.reference = "../etc";
  EXPECT_EQ(refusalOf([&] { manager.start(check); }), "bad_request");
  // The latest usable reference is the default: with none, a check is refused.
  EXPECT_EQ(refusalOf([&] { manager.start(kindOf(manager, SessionKind::kRestore)); }),
            "no_reference");
}

}  // namespace
}  // namespace zerocal::service
