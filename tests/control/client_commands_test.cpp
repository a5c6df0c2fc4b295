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
  EXPECT_EQ(run(args("abort")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("abort requested"));
  EXPECT_EQ(run(args("sessions")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("20261122-0001"));
  EXPECT_THAT(out_.str(), HasSubstr("unfinished"));
  EXPECT_EQ(run(args("result")), 0);
  EXPECT_THAT(out_.str(), HasSubstr("\"converged\": true"));
  auto a = args("result");
  a.session = "nope";
  EXPECT_EQ(run(a), 2);
  EXPECT_THAT(err_.str(), HasSubstr("not_found"));
}

TEST_F(ClientCommandsTest, PlanOnTheDaemon) {
  auto a = args("plan");
  a.poses = 9;
  EXPECT_EQ(run(a), 0);
  EXPECT_THAT(out_.str(), HasSubstr("fake plan of 9 poses"));
  EXPECT_THAT(out_.str(), HasSubstr("9 poses"));
  a.poses = 3;
  EXPECT_EQ(run(a), 2);
  EXPECT_EQ(session_.startCalls(), 0);
}

TEST_F(ClientCommandsTest, WatchFollowsTheSessionToItsEnd) {
  session_.start({});
  session_.setState(SessionState::kMoving, 1, 8);
  std::thread cell([this] {
    std::this_thread::sleep_for(200ms);
    session_.setState(SessionState::kServoing, 2, 8);
    session_.emit({{"event", "pose"}, {"pose", 2}, {"servo_error_um", 1.25}});
    std::this_thread::sleep_for(100ms);
    session_.setState(SessionState::kDone, 8, 8);
  });
  EXPECT_EQ(run(args("watch")), 0);
  cell.join();
  EXPECT_THAT(out_.str(), HasSubstr("moving  pose 1 of 8"));
  EXPECT_THAT(out_.str(), HasSubstr("servoing  pose 2 of 8"));
  EXPECT_THAT(out_.str(), HasSubstr("servo error 1.2 um"));
  EXPECT_THAT(out_.str(), HasSubstr("done"));
  // Plain lines: the final one once, with the recorded error, not the servo's live one.
  const std::string text = out_.str();
  const auto done = text.find("  done  ");
  ASSERT_NE(done, std::string::npos) << text;
  EXPECT_EQ(text.find("  done  ", done + 1), std::string::npos) << text;
  EXPECT_EQ(text.substr(done).find(" um now"), std::string::npos) << text;
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
