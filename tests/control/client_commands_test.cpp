// The zerocal client commands (src/cli/control_commands.cpp) against the control port and
// FakeSession: output, and the exit codes docs/cli.md promises.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "control_commands.h"
#include "server_fixture.h"

namespace zerocal::control {
namespace {

using service::SessionState;
using ::testing::HasSubstr;
using ::testing::Not;

class ClientCommandsTest : public ControlServerTest {
 protected:
  void SetUp() override {
    ControlServerTest::SetUp();
    token_file_ = writeToken(kToken, 0600);
  }
  void TearDown() override {
    for (const auto& f : files_) std::filesystem::remove(f);
    ControlServerTest::TearDown();
  }

  std::string writeToken(const std::string& content, mode_t mode) {
    const auto path =
        (std::filesystem::temp_directory_path() /
         ("zerocal-cli-token-" + std::to_string(::getpid()) + "-" + std::to_string(files_.size())))
            .string();
    std::ofstream(path) << content << "\n";
    ::chmod(path.c_str(), mode);
    files_.push_back(path);
    return path;
  }

  cli::ClientArgs args(const std::string& command) {
    cli::ClientArgs a;
    a.command = command;
    a.port = server_->port();
    a.token_file = token_file_;
    return a;
  }

  int run(const cli::ClientArgs& a) {
    out_.str("");
    err_.str("");
    return cli::runClient(a, out_, err_, false);
  }

  std::string token_file_;
  std::vector<std::string> files_;
  std::ostringstream out_, err_;
};

TEST_F(ClientCommandsTest, StatusAsTextAndJson) {
  session_.setState(SessionState::kServoing, 2, 8);
  EXPECT_EQ(run(args("status")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("state:      servoing (active)"));
  auto a = args("status");
  a.json = true;
  EXPECT_EQ(run(a), 0);
  EXPECT_EQ(nlohmann::json::parse(out_.str())["pose"], 2);
}

TEST_F(ClientCommandsTest, StartThenASecondStartIsRefusedWithExitCode2) {
  auto a = args("start");
  a.pattern = "II";
  a.poses = 10;
  a.target = {900, -50, 400};
  EXPECT_EQ(run(a), 0);
  EXPECT_THAT(out_.str(), HasSubstr("session 20261122-0001 started"));
  EXPECT_EQ(session_.lastRequest().poses, 10);
  EXPECT_EQ(session_.lastRequest().plan, PlanKind::kII);
  EXPECT_EQ(run(a), 2);
  EXPECT_THAT(err_.str(), HasSubstr("start refused (busy)"));
}

TEST_F(ClientCommandsTest, StartNotIdentifiableIsExitCode4) {
  auto a = args("start");
  a.poses = 7;
  EXPECT_EQ(run(a), 4);
}

TEST_F(ClientCommandsTest, NoDaemonIsExitCode5) {
  auto a = args("status");
  a.port = 1;
  EXPECT_EQ(run(a), 5);
  EXPECT_THAT(err_.str(), HasSubstr("cannot connect to 127.0.0.1:1"));
}

TEST_F(ClientCommandsTest, WrongOrUnusableTokenIsExitCode6) {
  auto a = args("start");
  a.token_file = writeToken("not-the-token-of-this-daemon", 0600);
  EXPECT_EQ(run(a), 6);
  EXPECT_THAT(err_.str(), HasSubstr("auth_failed"));
  a.token_file = writeToken(kToken, 0644);
  EXPECT_EQ(run(a), 6);
  EXPECT_THAT(err_.str(), HasSubstr("chmod 600"));
  a.token_file = "/nonexistent/token";
  EXPECT_EQ(run(a), 6);
  EXPECT_EQ(session_.startCalls(), 0);
}

TEST_F(ClientCommandsTest, AbortResumeSessionsResult) {
  EXPECT_EQ(run(args("abort")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("no session was running"));
  EXPECT_EQ(run(args("resume")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("resumed"));
  EXPECT_EQ(session_.lastResume().skip_pose, 0);
  session_.setState(service::SessionState::kFaulted);
  auto skip = args("resume");
  skip.session = "20261122-0001";
  skip.skip_pose = 3;
  EXPECT_EQ(run(skip), 0);
  EXPECT_EQ(session_.lastResume().skip_pose, 3);
  EXPECT_EQ(session_.lastResume().session, "20261122-0001");
  EXPECT_EQ(run(args("abort")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("abort requested"));
  EXPECT_EQ(run(args("sessions")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("20261122-0001"));
  EXPECT_THAT(out_.str(), HasSubstr("unfinished"));
  EXPECT_THAT(out_.str(), HasSubstr("1 of them skipped"));
  auto as_json = args("result");
  as_json.json = true;
  // The exit status says what the result says: this one has no offsets to offer.
  EXPECT_EQ(run(as_json), cli::kClientNotUsable);
  EXPECT_THAT(out_.str(), HasSubstr("\"converged\": true"));
  EXPECT_EQ(run(args("result")), cli::kClientNotUsable);
  EXPECT_THAT(out_.str(), HasSubstr("verdict: NOT USABLE"));
  EXPECT_THAT(out_.str(), HasSubstr("the result carries no offsets"));
  auto a = args("result");
  a.session = "nope";
  EXPECT_EQ(run(a), 2);
  EXPECT_THAT(err_.str(), HasSubstr("not_found"));
}

// A robot's record as the fake daemon holds it: two robots of one serial, a calibration applied
// and verified, then a verification.
void fillRecord(testing::FakeSession& session) {
  session.robot_list = {
      {{"IRB 1600-10/1.45", "SN-0001"}, "6.13.02", 2, 1'795'000'000, 1'795'003'600},
      {{"IRB 2600-20/1.65", "SN-0001"}, "7.1.0", 1, 1'795'000'000, 1'795'000'000}};
  record::HistoryEntry calibration;
  record::SessionEntry& c = calibration.session;
  c.session = "20261122T070000Z";
  c.robot = {"IRB 1600-10/1.45", "SN-0001"};
  c.kind = "calibration";
  c.usable = true;
  c.offsets = {record::RecordedOffset{0.31, 0.002}, record::RecordedOffset{-0.52, 0.003},
               std::nullopt, record::RecordedOffset{0.05, 0.005}};
  c.cell_time_s = 61.5;
  c.started_unix_s = 1'795'000'000;
  c.software_version = "6.13.02";
  c.model_file = "model.yaml";
  record::ControllerEvent apply;
  apply.outcome = "verified";
  apply.time_unix_s = 1'795'000'200;
  apply.before_rad = std::array<double, 6>{1, 2, 3, 3.2, 5, 6};
  apply.after_rad = std::array<double, 6>{1, 2.000541, 3, 3.2, 5, 6};
  apply.verification = "20261122T080000Z";
  calibration.events = {apply};
  record::HistoryEntry verification;
  verification.session = c;
  verification.session.session = "20261122T080000Z";
  verification.session.kind = "verification";
  verification.session.usable.reset();
  verification.session.reasons = {"one, with a comma"};
  verification.session.started_unix_s = 1'795'003'600;
  verification.session.model_file.clear();
  verification.session.model_from = "20261120T000000Z";
  session.history_list = {calibration, verification};
}

TEST_F(ClientCommandsTest, RobotsAndAHistoryAsTextCsvAndJson) {
  fillRecord(session_);
  EXPECT_EQ(run(args("robots")), 0);
  EXPECT_THAT(out_.str(),
              HasSubstr("IRB 1600-10/1.45 serial SN-0001  software 6.13.02  2 sessions"));
  EXPECT_THAT(out_.str(), HasSubstr("IRB 2600-20/1.65 serial SN-0001"));

  auto h = args("history");
  h.serial = "SN-0001";
  EXPECT_EQ(run(h), 2) << "the serial names two robots";
  EXPECT_THAT(err_.str(), HasSubstr("several robots"));
  h.robot_type = "IRB 1600-10/1.45";
  EXPECT_EQ(run(h), 0) << err_.str();
  const std::string text = out_.str();
  EXPECT_THAT(text, HasSubstr("IRB 1600-10/1.45 serial SN-0001: 2 sessions"));
  EXPECT_THAT(text, HasSubstr("2026-11-18"));
  EXPECT_THAT(text, HasSubstr("calibration  usable"));
  EXPECT_THAT(text, HasSubstr("+0.31000 +- 0.00200"));
  EXPECT_THAT(text, HasSubstr("withheld"));
  EXPECT_THAT(text, HasSubstr("apply verified: cal_offset rob1_2 2.000000 rob1_3 3.000000"));
  EXPECT_THAT(text, HasSubstr("-> rob1_2 2.000541"));
  EXPECT_THAT(text, HasSubstr("no verdict"));
  EXPECT_THAT(text, HasSubstr("wrote the robot's calibrated model (model.yaml)"));
  EXPECT_THAT(text, HasSubstr("solved with the calibrated model of 20261120T000000Z"));

  h.csv = true;
  EXPECT_EQ(run(h), 0);
  std::istringstream csv(out_.str());
  std::string header, first, second, rest;
  std::getline(csv, header);
  std::getline(csv, first);
  std::getline(csv, second);
  EXPECT_FALSE(std::getline(csv, rest));
  EXPECT_EQ(
      header,
      "robot_type,serial,session,started_utc,finished_utc,kind,verifies,usable,delta2_deg,"
      "delta2_deg_sigma,delta3_deg,delta3_deg_sigma,delta4_deg,delta4_deg_sigma,delta5_deg,"
      "delta5_deg_sigma,cell_time_s,software_version,controller_events,model_from,model_file");
  EXPECT_THAT(first, HasSubstr("IRB 1600-10/1.45,SN-0001,20261122T070000Z,"));
  EXPECT_THAT(first, HasSubstr(",calibration,,true,0.310000,0.002000,-0.520000,0.003000,,,"));
  EXPECT_THAT(first, HasSubstr(",61.5,6.13.02,apply verified,,model.yaml"));
  EXPECT_THAT(second, HasSubstr(",verification,,,"));
  EXPECT_THAT(second, HasSubstr(",20261120T000000Z,"));

  h.csv = false;
  h.json = true;
  EXPECT_EQ(run(h), 0);
  const nlohmann::json j = nlohmann::json::parse(out_.str());
  EXPECT_EQ(j["robot"]["serial"], "SN-0001");
  EXPECT_EQ(j["history"][0]["events"][0]["kind"], "apply");
  EXPECT_TRUE(j["history"][0]["offsets"]["delta4_deg"].is_null());
  EXPECT_TRUE(j["history"][1]["usable"].is_null());
  EXPECT_EQ(j["history"][0]["model_file"], "model.yaml");
  EXPECT_FALSE(j["history"][0].contains("model_from"));
  EXPECT_EQ(j["history"][1]["model_from"], "20261120T000000Z");

  h.serial = "SN-9999";
  h.json = false;
  EXPECT_EQ(run(h), 2);
  EXPECT_THAT(err_.str(), HasSubstr("no robot of serial SN-9999"));
}

TEST_F(ClientCommandsTest, ADaemonWithoutARecordSaysSo) {
  session_.record_kept = false;
  EXPECT_EQ(run(args("robots")), 2);
  EXPECT_THAT(err_.str(), HasSubstr("no_record"));
  EXPECT_EQ(run(args("history")), 2);
  EXPECT_THAT(err_.str(), HasSubstr("keeps no robot's record"));
}

TEST_F(ClientCommandsTest, SessionsShowsTheNewestWithAHintAndFollowsPagesForMore) {
  session_.session_list.clear();
  for (int i = 0; i < 2500; ++i)
    session_.session_list.push_back(SessionInfo{"20261122-" + std::to_string(10000 + i),
                                                "/tmp/s" + std::to_string(i), true, 8, 8, 0, ""});
  const auto lines = [this] {
    const std::string text = out_.str();
    return std::count(text.begin(), text.end(), '\n');
  };
  EXPECT_EQ(run(args("sessions")), 0);
  EXPECT_EQ(out_.str().find("20261122-12499"), 0u) << out_.str();  // the newest first
  EXPECT_THAT(out_.str(), HasSubstr("20261122-12480"));
  EXPECT_THAT(out_.str(), Not(HasSubstr("20261122-12479")));
  EXPECT_THAT(out_.str(),
              HasSubstr("the newest 20 of 2500 sessions; --limit N for more, --all for every one"));
  auto more = args("sessions");
  more.limit = 1500;  // beyond one page of the daemon's
  EXPECT_EQ(run(more), 0);
  EXPECT_EQ(lines(), 1501);
  EXPECT_THAT(out_.str(), HasSubstr("20261122-11000 "));
  EXPECT_THAT(out_.str(), Not(HasSubstr("20261122-10999")));
  auto all = args("sessions");
  all.all = true;
  all.json = true;
  EXPECT_EQ(run(all), 0);
  const auto list = nlohmann::json::parse(out_.str());
  ASSERT_EQ(list.size(), 2500u);
  EXPECT_EQ(list.front()["id"], "20261122-12499");
  EXPECT_EQ(list.back()["id"], "20261122-10000");
}

// A result without the solver's verdict (as written before verdicts were recorded), of a
// simulated session whose delta5 is not identifiable.
ResultFile offsetsResult() {
  ResultFile r;
  r.verdict_recorded = false;
  r.session = "20261122-0000";
  r.report.converged = true;
  r.report.message = "converged";
  r.report.pose_count = 8;
  r.cell_time_s = 84.25;
  const std::array<double, 3> values{0.41203, -0.2, 0.7}, sigmas{0.002, 0.001, 0.003};
  for (int k = 0; k < 3; ++k) {
    ParameterEstimate p;
    p.name = "delta" + std::to_string(k + 2) + "_deg";
    p.value = values[k];
    p.sigma = sigmas[k];
    p.ci95_low = values[k] - 2.5 * sigmas[k];
    p.ci95_high = values[k] + 2.5 * sigmas[k];
    r.report.parameters.push_back(p);
  }
  ParameterEstimate delta5;
  delta5.name = "delta5_deg";
  delta5.identifiable = false;
  delta5.reason = "joint 5 never moved";
  r.report.parameters.push_back(delta5);
  r.truth = ResultFile::Truth{{0.412, NAN, NAN, NAN}, ""};
  return r;
}

TEST_F(ClientCommandsTest, ResultOpensWithTheVerdictThenTheOffsetsAndWhatToDo) {
  session_.result_value = offsetsResult();
  EXPECT_EQ(run(args("result")), cli::kClientNotUsable);
  const std::string text = out_.str();
  EXPECT_THAT(text, HasSubstr("(SIMULATED cell: the truth is known)"));
  // Without the solver's verdict: convergence and identifiability decide.
  EXPECT_THAT(text, HasSubstr("verdict: NOT USABLE (convergence and identifiability only)\n"
                              "  - delta5 is not identifiable from these poses\n"));
  EXPECT_THAT(text, HasSubstr("delta2      +0.41203     0.00200   [+0.40703, +0.41703]"));
  EXPECT_THAT(text, HasSubstr("+0.41200   +0.00003"));  // truth and error
  EXPECT_THAT(text, HasSubstr("delta5  not identifiable: joint 5 never moved"));
  EXPECT_THAT(text, HasSubstr("change nothing: the verdict is not usable"));
  // What to do next, after the reasons.
  EXPECT_THAT(text, HasSubstr("next: nothing was written. To determine every offset absolutely, "
                              "calibrate at several PSD placements (`zerocal start --placements "
                              "3`"));
  EXPECT_THAT(text, HasSubstr("cell time 84.2 s, 8 poses"));
  EXPECT_LT(text.find("verdict:"), text.find("delta2 "));

  // The solver's own verdict, when result.json carries one, is the one shown.
  session_.result_value.verdict_recorded = true;
  session_.result_value.report.verdict = {true, {}};
  EXPECT_EQ(run(args("result")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("verdict: USABLE\n"));
  EXPECT_THAT(
      out_.str(),
      HasSubstr("joint 2: the reading grows by +0.41203 deg (its zero moves -0.41203 deg)"));
  session_.result_value.report.verdict = {false, {"chi-square per dof 7.1: the poses miss"}};
  EXPECT_EQ(run(args("result")), cli::kClientNotUsable);
  EXPECT_THAT(out_.str(),
              HasSubstr("verdict: NOT USABLE\n  - chi-square per dof 7.1: the poses miss\n"));
  // Refused: every offset withheld, as in summary.txt and report.html.
  EXPECT_THAT(out_.str(), HasSubstr("delta2  withheld: the result is not usable\n"));
  EXPECT_THAT(out_.str(), Not(HasSubstr("+0.41203")));
  EXPECT_THAT(out_.str(), Not(HasSubstr("robot:")));  // not recorded: nothing made up
  // The robot as its controller named itself, right after the verdict.
  session_.result_value.cell = ResultFile::Cell{{"1600-504321", "6.15", "IRB 1600-10/1.45"}, ""};
  EXPECT_EQ(run(args("result")), cli::kClientNotUsable);
  EXPECT_THAT(out_.str(),
              HasSubstr("robot: IRB 1600-10/1.45, serial 1600-504321, RobotWare 6.15\n"));

  // Once applied and verified, the controller holds the values: the result says so instead of
  // how to enter them.
  session_.result_value.report.verdict = {true, {}};
  apply::ApplyRecord applied;
  applied.outcome = "verified";
  applied.time_unix_s = 1796396424;
  applied.verification = "20261122-0002";
  applied.message = "every remaining offset of joints 2..5 is within max(3 sigma, 0.0100 deg)";
  session_.last_apply = applied;
  EXPECT_EQ(run(args("result")), 0);
  EXPECT_THAT(out_.str(),
              HasSubstr("Written to the controller on 2026-12-04 15:00 UTC, verified by "
                        "session 20261122-0002"));
  EXPECT_THAT(out_.str(), HasSubstr("do not enter them again"));
  EXPECT_THAT(out_.str(), Not(HasSubstr("nothing was written")));
  applied.outcome = "rolled_back";
  session_.last_apply = applied;
  EXPECT_EQ(run(args("result")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("the controller holds its values from before the apply"));

  // A check that found a zero moved exits 9, whatever its verdict.
  session_.last_apply.reset();
  session_.result_value.kind = SessionKind::kCheck;
  session_.result_value.reference = "20261122-0000";
  session_.result_value.check = CheckJudgement{};
  session_.result_value.check->outcome = CheckJudgement::Outcome::kChanged;
  EXPECT_EQ(run(args("result")), cli::kClientCheckNotPassed);
  session_.result_value.check->outcome = CheckJudgement::Outcome::kPass;
  EXPECT_EQ(run(args("result")), 0);
}

TEST_F(ClientCommandsTest, VersionShowsTheDaemonsVersionAndProtocolWhenOneAnswers) {
  EXPECT_EQ(run(args("version")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("zerocal " PROJECT_VERSION "\n"));
  EXPECT_THAT(out_.str(), HasSubstr("zerocald 9.9.9 at 127.0.0.1:" +
                                    std::to_string(server_->port()) + ", control protocol 1\n"));
  auto a = args("version");
  a.port = 1;  // nobody there
  EXPECT_EQ(run(a), 0);
  EXPECT_THAT(out_.str(), HasSubstr("zerocald: none answers at 127.0.0.1:1"));
  a.json = true;
  EXPECT_EQ(run(a), 0);
  EXPECT_EQ(nlohmann::json::parse(out_.str())["zerocald"], nullptr);
}

TEST_F(ClientCommandsTest, PlanOnTheDaemon) {
  auto a = args("plan");
  a.poses = 9;
  EXPECT_EQ(run(a), 0);
  EXPECT_THAT(out_.str(), HasSubstr("fake plan of 9 poses"));
  EXPECT_THAT(out_.str(), HasSubstr("9 poses"));
  EXPECT_THAT(out_.str(), HasSubstr("about 47 s of cell time (5.2 s a pose in the daemon's "
                                    "latest 4 sessions)\n"));
  EXPECT_THAT(out_.str(), Not(HasSubstr("short of the required")));
  a.poses = 10;  // the fake daemon predicts delta2 to 0.02 deg against 0.01
  EXPECT_EQ(run(a), 0);
  EXPECT_THAT(out_.str(), HasSubstr("short of the required 0.0100 deg: delta2. `zerocal start` "
                                    "refuses this plan unless --even-if-not-usable"));
  EXPECT_THAT(out_.str(), HasSubstr("cell time not predicted: the daemon has no finished session"));
  a.poses = 3;
  EXPECT_EQ(run(a), 2);
  EXPECT_EQ(session_.startCalls(), 0);
}

TEST_F(ClientCommandsTest, WatchFollowsTheSessionToItsEnd) {
  session_.result_session = "20261122-0001";
  session_.result_value = offsetsResult();
  session_.result_value.verdict_recorded = true;
  session_.result_value.report.verdict = {true, {}};
  session_.start({});
  session_.setState(SessionState::kMoving, 1, 8);
  std::thread cell([this] {
    std::this_thread::sleep_for(200ms);
    session_.setState(SessionState::kServoing, 2, 8);
    session_.emit(testing::measuredPose(2, 1.25));
    std::this_thread::sleep_for(100ms);
    session_.setState(SessionState::kDone, 8, 8);
  });
  EXPECT_EQ(run(args("watch")), 0);
  cell.join();
  // On a pipe: a line per pose recorded, with its servo error and the zone it is judged by, and
  // a line per state outside the poses; no line per move.
  EXPECT_THAT(out_.str(), HasSubstr("pose 2 of 8 recorded: spot 1.2 um from its aim"));
  EXPECT_THAT(out_.str(), Not(HasSubstr("moving")));
  EXPECT_THAT(out_.str(), Not(HasSubstr("servoing")));
  EXPECT_THAT(out_.str(), HasSubstr("done"));
  EXPECT_THAT(out_.str(), HasSubstr("verdict: USABLE"));
  // Not usable: the watch's exit status says so.
  session_.result_value.report.verdict = {false, {"delta2 is not determined"}};
  session_.setState(SessionState::kDone, 8, 8);
  EXPECT_EQ(run(args("watch")), cli::kClientNotUsable);
  // Plain lines: the final one once, with the recorded error, not the servo's live one.
  const std::string text = out_.str();
  const auto done = text.find("  done  ");
  ASSERT_NE(done, std::string::npos) << text;
  EXPECT_EQ(text.find("  done  ", done + 1), std::string::npos) << text;
  EXPECT_EQ(text.substr(done).find(" um now"), std::string::npos) << text;
}

// `zerocal acknowledge` without --confirm sends nothing (exit 2); a daemon whose interrupted
// apply is not recovered is a failure to `watch` (exit 3), not a finished session.
TEST_F(ClientCommandsTest, AcknowledgeNeedsTheConfirmationAndUnrecoveredIsAFailure) {
  session_.setState(SessionState::kUnrecovered);
  EXPECT_EQ(run(args("acknowledge")), cli::kClientBadRequest);
  EXPECT_THAT(err_.str(), HasSubstr("--confirm"));
  EXPECT_EQ(run(args("watch")), cli::kClientSessionFailed);
  EXPECT_EQ(session_.status().state, SessionState::kUnrecovered);  // nothing reached the daemon
}

// A watch ends when the session waits for the PSD, saying where it goes (exit 0: nothing went
// wrong); `zerocal continue` goes on, with the centre as taught when given, and is refused with
// exit code 2 when nothing waits.
TEST_F(ClientCommandsTest, WatchStopsAtAPlacementAndContinueGoesOn) {
  auto start = args("start");
  start.placements = 2;
  EXPECT_EQ(run(start), 0);
  EXPECT_EQ(session_.lastRequest().placements, 2);
  EXPECT_EQ(run(args("continue")), cli::kClientBadRequest);
  EXPECT_THAT(err_.str(), HasSubstr("not_waiting"));
  session_.setState(SessionState::kRecording, 8, 16);
  std::thread cell([this] {
    std::this_thread::sleep_for(200ms);
    session_.awaitPlacement(2, 2, Eigen::Vector3d(613, 652.5, 585));
  });
  EXPECT_EQ(run(args("watch")), 0);
  cell.join();
  EXPECT_THAT(out_.str(), HasSubstr("awaiting_placement"));
  EXPECT_THAT(out_.str(), HasSubstr("move the PSD to placement 2"));
  EXPECT_EQ(run(args("status")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("placement:  1 of 2"));
  auto go_on = args("continue");
  go_on.centre = {614, 652.5, 585};
  EXPECT_EQ(run(go_on), 0);
  EXPECT_THAT(out_.str(), HasSubstr("continued at its next PSD placement"));
  ASSERT_TRUE(session_.lastContinue().centre_mm);
  EXPECT_EQ(session_.lastContinue().centre_mm->x(), 614);
}

TEST_F(ClientCommandsTest, WatchEndsWithTheVerdictAndTheOffsets) {
  session_.start({});
  session_.result_session = "20261122-0001";
  session_.result_value = offsetsResult();
  session_.result_value.verdict_recorded = true;
  session_.result_value.report.verdict = {true, {}};
  std::thread cell([this] {
    std::this_thread::sleep_for(100ms);
    session_.setState(SessionState::kDone, 8, 8);
  });
  EXPECT_EQ(run(args("watch")), 0);
  cell.join();
  const std::string text = out_.str();
  EXPECT_THAT(text, HasSubstr("verdict: USABLE"));
  EXPECT_THAT(text, HasSubstr("delta2      +0.41203"));
  EXPECT_EQ(text.find("achieved:"), std::string::npos) << text;
  EXPECT_LT(text.find("  done  "), text.find("verdict:")) << text;
}

TEST_F(ClientCommandsTest, WatchOfAnAbortedSessionIsExitCode3) {
  session_.start({});
  std::thread cell([this] {
    std::this_thread::sleep_for(200ms);
    session_.abort();
  });
  EXPECT_EQ(run(args("watch")), 3);
  cell.join();
  EXPECT_THAT(out_.str(), HasSubstr("aborted on request"));
}

TEST_F(ClientCommandsTest, StartWatchAsJsonLines) {
  session_.result_session = "20261122-0001";
  session_.result_value = offsetsResult();
  session_.result_value.verdict_recorded = true;
  session_.result_value.report.verdict = {true, {}};
  auto a = args("start");
  a.watch = true;
  a.json = true;
  std::thread cell([this] {
    std::this_thread::sleep_for(200ms);
    session_.setState(SessionState::kDone, 8, 8);
  });
  EXPECT_EQ(run(a), 0);
  cell.join();
  std::istringstream lines(out_.str());
  std::string line;
  int events = 0;
  while (std::getline(lines, line)) {
    const auto j = nlohmann::json::parse(line);  // every line is JSON
    events += j.contains("event");
  }
  EXPECT_GE(events, 1);
}

}  // namespace
}  // namespace zerocal::control
