// The control port over real TCP on loopback against FakeSession: every command, authentication,
// and each class of bad input, each followed by a check that another client is still served fast.
#include "zerocal/control/server.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <sys/stat.h>

#include <algorithm>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>
#include <filesystem>
#include <fstream>
#include <future>
#include <random>
#include <thread>

#include "fake_session.h"
#include "server_fixture.h"
#include "zerocal/control/client.h"
#include "zerocal/control/protocol.h"
#include "zerocal/control/token.h"
#include "zerocal/daemon/config.h"
#include "zerocal/daemon/logging.h"

namespace zerocal::control {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;
using service::SessionState;
using ::testing::HasSubstr;

// -- token file --------------------------------------------------------------------------------

class TokenFileTest : public ::testing::Test {
 protected:
  std::string write(const std::string& content, mode_t mode) {
    const auto path =
        (std::filesystem::temp_directory_path() /
         ("zerocal-token-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++)))
            .string();
    std::ofstream(path) << content;
    ::chmod(path.c_str(), mode);
    files_.push_back(path);
    return path;
  }
  void TearDown() override {
    for (const auto& f : files_) std::filesystem::remove(f);
  }
  std::vector<std::string> files_;
  int counter_ = 0;
};

TEST_F(TokenFileTest, ReadsAnOwnerOnlyFileWithoutSurroundingWhitespace) {
  EXPECT_EQ(loadToken(write("  s3cret-s3cret-s3cret\n", 0600)), "s3cret-s3cret-s3cret");
  EXPECT_EQ(loadToken(write("s3cret-s3cret-s3cret", 0400)), "s3cret-s3cret-s3cret");
}

TEST_F(TokenFileTest, RefusesATokenTooShortToGuardAnythingAndAFileTooLargeToBeOne) {
  EXPECT_THAT([&] { loadToken(write("x\n", 0600)); },
              ::testing::ThrowsMessage<Error>(HasSubstr("use at least 16")));
  EXPECT_THAT([&] { loadToken(write(std::string(5000, 'k'), 0600)); },
              ::testing::ThrowsMessage<Error>(HasSubstr("not a token")));
}

TEST_F(TokenFileTest, ReadsAFileItsGroupMayRead) {  // root:zerocal 0640, shared by technicians
  EXPECT_EQ(loadToken(write("s3cret-s3cret-s3cret", 0640)), "s3cret-s3cret-s3cret");
  EXPECT_EQ(loadToken(write("s3cret-s3cret-s3cret", 0440)), "s3cret-s3cret-s3cret");
}

TEST_F(TokenFileTest, RefusesAMissingFile) {
  EXPECT_THAT([] { loadToken("/nonexistent/zerocal-token"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("No such file")));
  EXPECT_THAT([] { loadToken(""); },
              ::testing::ThrowsMessage<Error>(HasSubstr("control.token_file is not set")));
}

TEST_F(TokenFileTest, RefusesAnEmptyFile) {
  const auto path = write(" \n", 0600);
  EXPECT_THAT([&] { loadToken(path); }, ::testing::ThrowsMessage<Error>(HasSubstr("is empty")));
}

TEST_F(TokenFileTest, RefusesAFileOthersMayAccessOrTheGroupMayChange) {
  for (mode_t mode : {0644, 0604, 0660, 0602, 0610, 0620, 0641}) {
    const auto path = write("s3cret", mode);
    EXPECT_THAT([&] { loadToken(path); }, ::testing::ThrowsMessage<Error>(HasSubstr("chmod 640")))
        << std::oct << mode;
  }
}

TEST_F(TokenFileTest, RefusesADirectory) {
  EXPECT_THAT([] { loadToken("/"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("not a regular file")));
}

TEST(TokensEqual, ComparesWholeStrings) {
  EXPECT_TRUE(tokensEqual("abc", "abc"));
  EXPECT_FALSE(tokensEqual("abd", "abc"));
  EXPECT_FALSE(tokensEqual("ab", "abc"));
  EXPECT_FALSE(tokensEqual("abcd", "abc"));
  EXPECT_FALSE(tokensEqual("", "abc"));
  EXPECT_FALSE(tokensEqual("", ""));  // an empty expected token never matches
}

TEST(ControlServerSetup, RefusesToStartWithoutAToken) {
  boost::asio::io_context io;
  testing::FakeSession session;
  EXPECT_THROW(ControlServer(io, session, ServerOptions{}), Error);
}

TEST(ControlServerSetup, TheControlSectionIsTheServersOptions) {
  DaemonConfig config;
  ConfigOrigins origins;
  std::vector<std::string> problems;
  for (const char* assignment : {"control.idle_timeout_s=1.5", "control.max_queued_kib=64"})
    applyConfigOverride(config, assignment, origins, problems);
  EXPECT_TRUE(problems.empty());
  const ServerOptions& o = config.control;
  EXPECT_EQ(o.bind_address, "127.0.0.1");
  EXPECT_EQ(o.port, 7450);
  EXPECT_EQ(o.max_line_bytes, 65536u);
  EXPECT_EQ(o.idle_timeout, 1500ms);
  EXPECT_EQ(o.max_queued_bytes, 65536u);
  EXPECT_EQ(o.max_auth_failures, 3);
  EXPECT_EQ(configToJson(config)["control"]["idle_timeout_s"], 1.5);
  EXPECT_EQ(configToJson(config)["control"]["max_queued_kib"], 64);
}

TEST(ControlServerSetup, ReportsAPortInUse) {
  boost::asio::io_context io;
  testing::FakeSession session;
  ServerOptions options;
  options.token = kToken;
  options.port = 0;
  ControlServer first(io, session, options);
  first.start();
  options.port = first.port();
  ControlServer second(io, session, options);
  EXPECT_THAT([&] { second.start(); },
              ::testing::ThrowsMessage<Error>(HasSubstr("cannot listen on 127.0.0.1")));
}

// -- open commands and authentication ----------------------------------------------------------

TEST_F(ControlServerTest, HelloAndVersionNeedNoToken) {
  auto c = connect(false);
  const auto hello = c->call("hello");
  EXPECT_EQ(hello["protocol"], kProtocolVersion);
  EXPECT_EQ(hello["daemon"], "9.9.9");
  EXPECT_EQ(hello["authenticated"], false);
  EXPECT_THAT(hello["commands"].dump(), HasSubstr("\"subscribe\""));
  const auto version = c->call("version");
  EXPECT_EQ(version["protocol"], kProtocolVersion);
}

TEST_F(ControlServerTest, ResponsesEchoAnyId) {
  auto c = connect(false);
  c->sendRaw("{\"id\": {\"mine\": [1, \"x\"]}, \"cmd\": \"version\"}\n");
  const auto r = json::parse(*c->readLine(1s));
  EXPECT_EQ(r["id"], json::parse("{\"mine\": [1, \"x\"]}"));
  EXPECT_EQ(r["ok"], true);
}

TEST_F(ControlServerTest, EveryOtherCommandNeedsAuthentication) {
  auto c = connect(false);
  for (const char* cmd : {"status", "start"}) {
    const auto r = c->request({{"cmd", cmd}});
    EXPECT_EQ(r["ok"], false);
    EXPECT_EQ(r["error"]["code"], "unauthenticated") << cmd;
  }
  EXPECT_EQ(session_.startCalls(), 0);
}

TEST_F(ControlServerTest, NoRobotCommandIsAcceptedWithoutTheToken) {
  session_.setState(SessionState::kMoving, 1, 8);
  for (const char* cmd : {"start", "abort", "resume", "psd", "plan"}) {
    auto c = connect(false);
    const auto r = c->request({{"cmd", cmd}, {"token", "guess"}});
    EXPECT_EQ(r["error"]["code"], "unauthenticated") << cmd;
  }
  EXPECT_EQ(session_.startCalls(), 0);
  EXPECT_EQ(session_.abortCalls(), 0);
  EXPECT_EQ(session_.status().state, SessionState::kMoving);
}

TEST_F(ControlServerTest, WrongTokenIsRefusedLoggedAndTheConnectionClosedAfterThree) {
  auto ring = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(20);
  makeLogger("control")->sinks().push_back(ring);
  auto c = connect(false);
  for (int i = 0; i < 3; ++i) {
    const auto r = c->request({{"cmd", "auth"}, {"token", i == 1 ? json(42) : json("wrong")}});
    EXPECT_EQ(r["error"]["code"], "auth_failed");
    if (i == 2) {
      EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("closing"));
    }
  }
  expectClosed(*c);
  makeLogger("control")->sinks().pop_back();
  std::string logged;
  for (const auto& line : ring->last_formatted()) logged += line;
  EXPECT_THAT(logged, HasSubstr("127.0.0.1:"));
  EXPECT_THAT(logged, HasSubstr("authentication failed (auth_failed, 3 of 3); closing"));
  expectOthersServedFast();
}

TEST_F(ControlServerTest, CommandsBeforeAuthCountAsFailures) {
  auto c = connect(false);
  for (int i = 0; i < 3; ++i) c->request({{"cmd", "status"}});
  expectClosed(*c);
}

TEST_F(ControlServerTest, AuthenticationHoldsForTheConnection) {
  auto c = connect(false);
  EXPECT_EQ(c->call("auth", {{"token", kToken}})["ok"], true);
  EXPECT_EQ(c->call("hello")["authenticated"], true);
  EXPECT_EQ(c->call("status")["ok"], true);
  auto other = connect(false);
  EXPECT_EQ(other->request({{"cmd", "status"}})["error"]["code"], "unauthenticated");
}

// The operator's token: watch, read, plan, check the zeros and abort; nothing that calibrates
// or writes into the controller.
TEST_F(ControlServerTest, AnOperatorChecksAndAbortsButNeitherCalibratesNorWrites) {
  constexpr const char* kOperatorToken = "operator-7450-checks-only";
  ServerOptions o;
  o.operator_token = kOperatorToken;
  startServer(o);
  auto c = connect(false);
  EXPECT_EQ(c->request({{"cmd", "auth"}, {"token", kOperatorToken}})["role"], "operator");
  EXPECT_EQ(c->call("hello")["role"], "operator");
  EXPECT_TRUE(c->call("status")["status"].is_object());
  EXPECT_EQ(c->request({{"cmd", "plan"}, {"poses", 8}})["ok"], true);
  for (const json& request :
       {json{{"cmd", "start"}}, json{{"cmd", "start"}, {"kind", "reference"}},
        json{{"cmd", "start"}, {"kind", "calibrate"}, {"placements", 3}},
        json{{"cmd", "apply"}, {"session", "x"}, {"confirm", true}},
        json{{"cmd", "verify"}, {"session", "x"}}, json{{"cmd", "acknowledge"}},
        json{{"cmd", "resume"}}, json{{"cmd", "continue"}}}) {
    const json r = c->request(request);
    EXPECT_EQ(r["error"]["code"], "forbidden") << request << r;
    EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("engineer's token"));
  }
  EXPECT_EQ(session_.startCalls(), 0);
  EXPECT_EQ(session_.applyCalls(), 0);
  EXPECT_EQ(c->request({{"cmd", "start"}, {"kind", "check"}})["ok"], true);
  EXPECT_EQ(session_.startCalls(), 1);
  EXPECT_EQ(c->request({{"cmd", "abort"}})["ok"], true);
  // The engineer's token, on the same connection or another, may do all of it.
  EXPECT_EQ(connect()->call("hello")["role"], "engineer");
  EXPECT_EQ(c->request({{"cmd", "auth"}, {"token", kToken}})["role"], "engineer");
  EXPECT_NE(c->request({{"cmd", "start"}, {"kind", "restore"}})["error"]["code"], "forbidden");
  // Without an operator token configured, no other token logs in.
  startServer(ServerOptions{});
  EXPECT_EQ(connect(false)->request({{"cmd", "auth"}, {"token", kOperatorToken}})["error"]["code"],
            "auth_failed");
}

TEST_F(ControlServerTest, AStatusPollerLeavesNoLineInTheLogAtInfo) {
  auto ring = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(20);
  makeLogger("control")->sinks().push_back(ring);
  for (int i = 0; i < 5; ++i) {  // `watch -n1 zerocal status`: a connection per poll
    auto c = connect();
    EXPECT_EQ(c->call("status")["ok"], true);
  }
  makeLogger("control")->sinks().pop_back();
  EXPECT_THAT(ring->last_formatted(), ::testing::IsEmpty());
}

// -- commands ----------------------------------------------------------------------------------

TEST_F(ControlServerTest, Status) {
  session_.setState(SessionState::kServoing, 3, 8);
  const auto s = connect()->call("status")["status"];
  EXPECT_EQ(s["state"], "servoing");
  EXPECT_EQ(s["active"], true);
  EXPECT_EQ(s["pose"], 3);
  EXPECT_EQ(s["pose_count"], 8);
  EXPECT_EQ(s["live_servo_error_um"], 12.5);
  session_.setState(SessionState::kMoving, 4, 8);
  EXPECT_TRUE(connect()->call("status")["status"]["live_servo_error_um"].is_null());
}

TEST_F(ControlServerTest, StartPassesThePlanChoice) {
  auto c = connect();
  const auto r = c->call(
      "start",
      {{"plan", "II"}, {"poses", 10}, {"target_mm", {900, -50, 400.5}}, {"noise_mm", 0.02}});
  EXPECT_EQ(r["session"], "20261122-0001");
  const auto req = session_.lastRequest();
  EXPECT_EQ(req.plan, PlanKind::kII);
  EXPECT_EQ(req.poses, 10);
  ASSERT_TRUE(req.target_mm);
  EXPECT_DOUBLE_EQ(req.target_mm->z(), 400.5);
  EXPECT_DOUBLE_EQ(req.noise_mm.value_or(0), 0.02);
  EXPECT_FALSE(req.even_if_not_usable);
  session_.setState(service::SessionState::kIdle);
  c->call("start", {{"even_if_not_usable", true}});
  EXPECT_TRUE(session_.lastRequest().even_if_not_usable);
  EXPECT_EQ(session_.lastRequest().kind, SessionKind::kCalibration);
  session_.setState(service::SessionState::kIdle);
  c->call("start", {{"kind", "restore"}, {"reference", "20261121T060000Z"}});
  EXPECT_EQ(session_.lastRequest().kind, SessionKind::kRestore);
  EXPECT_EQ(session_.lastRequest().reference, "20261121T060000Z");
  session_.setState(service::SessionState::kIdle);
  c->call("start", {{"kind", "calibrate"}});
  EXPECT_EQ(session_.lastRequest().kind, SessionKind::kCalibration);
  // NaN (not identifiable) travels as null.
  EXPECT_TRUE(c->call("status")["status"]["predicted_sigma_deg"][2].is_null());
}

TEST_F(ControlServerTest, ASecondStartIsRefusedWithTheReason) {
  auto a = connect();
  auto b = connect();
  a->call("start");
  const auto r = b->request({{"cmd", "start"}});
  EXPECT_EQ(r["ok"], false);
  EXPECT_EQ(r["error"]["code"], "busy");
  EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("one session at a time"));
}

TEST_F(ControlServerTest, StartRefusedWhenNotIdentifiable) {
  const auto r = connect()->request({{"cmd", "start"}, {"poses", 7}});
  EXPECT_EQ(r["error"]["code"], "not_identifiable");
}

TEST_F(ControlServerTest, Abort) {
  auto c = connect();
  EXPECT_EQ(c->call("abort")["aborted"], false);
  c->call("start");
  EXPECT_EQ(c->call("abort")["aborted"], true);
  EXPECT_EQ(c->call("status")["status"]["state"], "aborted");
}

TEST_F(ControlServerTest, Resume) {
  auto c = connect();
  EXPECT_EQ(c->call("resume")["session"], "20261122-0001");
  EXPECT_EQ(c->request({{"cmd", "resume"}})["error"]["code"], "busy");
  session_.setState(SessionState::kAborted);
  EXPECT_EQ(c->request({{"cmd", "resume"}, {"session", "nope"}})["error"]["code"], "not_found");
  EXPECT_EQ(c->call("resume", {{"session", "20261122-0001"}})["session"], "20261122-0001");
  EXPECT_EQ(session_.lastResume().skip_pose, 0);
  session_.setState(SessionState::kFaulted);
  // A pose to skip reaches the session as given; a malformed one, or a misspelt member, does not.
  for (const json& bad : {json("2"), json(0), json(-1), json(2.5), json(201)})
    EXPECT_EQ(c->request({{"cmd", "resume"}, {"skip_pose", bad}})["error"]["code"], "bad_request")
        << bad;
  EXPECT_EQ(c->request({{"cmd", "resume"}, {"skip", 2}})["error"]["code"], "bad_request");
  EXPECT_EQ(session_.lastResume().skip_pose, 0);
  c->call("resume", {{"skip_pose", 2}});
  EXPECT_EQ(session_.lastResume().skip_pose, 2);
  EXPECT_TRUE(session_.lastResume().session.empty());
}

// An interrupted apply the daemon could not recover: the status says so, and `acknowledge`
// needs the technician's confirmation; a misspelt or mistyped member never reaches the session.
TEST_F(ControlServerTest, AcknowledgeNeedsTheConfirmationAndClosesAnUnrecoveredApply) {
  auto c = connect();
  EXPECT_EQ(c->request({{"cmd", "acknowledge"}, {"confirm", true}})["error"]["code"], "not_found");
  session_.setState(SessionState::kUnrecovered);
  const json s = c->call("status")["status"];
  EXPECT_EQ(s["state"], "unrecovered");
  EXPECT_EQ(s["active"], false);
  EXPECT_EQ(c->request({{"cmd", "acknowledge"}})["error"]["code"], "not_confirmed");
  EXPECT_EQ(c->request({{"cmd", "acknowledge"}, {"confirm", "yes"}})["error"]["code"],
            "bad_request");
  EXPECT_EQ(c->request({{"cmd", "acknowledge"}, {"confirmed", true}})["error"]["code"],
            "bad_request");
  EXPECT_EQ(c->call("status")["status"]["state"], "unrecovered");
  EXPECT_TRUE(c->call("acknowledge", {{"confirm", true}}).contains("session"));
  EXPECT_EQ(c->call("status")["status"]["state"], "done");
}

// Only a session waiting for the PSD goes on; the status says where the PSD goes, and the
// placement's taught centre reaches the session as given.
TEST_F(ControlServerTest, ContinueGoesOnOnlyWithASessionWaitingForThePsd) {
  auto c = connect();
  const json idle = c->request({{"cmd", "continue"}});
  EXPECT_EQ(idle["error"]["code"], "not_waiting");
  c->call("start", {{"placements", 3}});
  EXPECT_EQ(session_.lastRequest().placements, 3);
  EXPECT_EQ(c->request({{"cmd", "continue"}})["error"]["code"], "not_waiting");  // measuring
  session_.awaitPlacement(2, 3, Eigen::Vector3d(613, 652.5, 585));
  const json s = c->call("status")["status"];
  EXPECT_EQ(s["state"], "awaiting_placement");
  EXPECT_EQ(s["active"], true);
  EXPECT_EQ(s["next_placement"], 2);
  EXPECT_EQ(s["next_centre_mm"], json({613, 652.5, 585}));
  EXPECT_EQ(s["placement_count"], 3);
  for (const json& bad : {json({1, 2}), json("613 652 585"), json({1, 2, "x"})})
    EXPECT_EQ(c->request({{"cmd", "continue"}, {"centre_mm", bad}})["error"]["code"], "bad_request")
        << bad;
  EXPECT_EQ(c->request({{"cmd", "continue"}, {"centre", {1, 2, 3}}})["error"]["code"],
            "bad_request");
  EXPECT_EQ(c->call("continue", {{"centre_mm", {614, 652.5, 585.25}}})["session"], "20261122-0001");
  ASSERT_TRUE(session_.lastContinue().centre_mm);
  EXPECT_EQ(*session_.lastContinue().centre_mm, Eigen::Vector3d(614, 652.5, 585.25));
  const json after = c->call("status")["status"];
  EXPECT_EQ(after["placement"], 2);
  EXPECT_FALSE(after.contains("next_placement"));
  for (const json& bad : {json(0), json(6), json(2.5), json("2")})
    EXPECT_EQ(c->request({{"cmd", "start"}, {"placements", bad}})["error"]["code"], "bad_request")
        << bad;
}

TEST_F(ControlServerTest, ThePlacementEventSaysWhereThePsdGoes) {
  const json e = toJson(service::SessionEvent(service::PlacementEvent{
      "20261122-0001", 2, 3, Eigen::Vector3d(613, 652.5, 585), "move the PSD"}));
  EXPECT_EQ(e, (json{{"event", "placement"},
                     {"session", "20261122-0001"},
                     {"placement", 2},
                     {"placement_count", 3},
                     {"centre_mm", {613, 652.5, 585}},
                     {"message", "move the PSD"}}));
}

TEST_F(ControlServerTest, ApplyNeedsTheConfirmationAndIsRefusedWhileBusy) {
  auto c = connect();
  EXPECT_EQ(c->request({{"cmd", "apply"}})["error"]["code"], "not_confirmed");
  EXPECT_EQ(c->request({{"cmd", "apply"}, {"confirm", false}})["error"]["code"], "not_confirmed");
  // "true" as a string is not a confirmation; a misspelt member is not ignored.
  EXPECT_EQ(c->request({{"cmd", "apply"}, {"confirm", "true"}})["error"]["code"], "bad_request");
  EXPECT_EQ(c->request({{"cmd", "apply"}, {"confirm", true}, {"sesion", "x"}})["error"]["code"],
            "bad_request");
  EXPECT_EQ(session_.applyCalls(), 0);
  session_.setState(SessionState::kMoving, 1, 8);
  EXPECT_EQ(c->request({{"cmd", "apply"}, {"confirm", true}})["error"]["code"], "busy");
  EXPECT_EQ(c->request({{"cmd", "verify"}})["error"]["code"], "busy");
  session_.setState(SessionState::kDone);
  EXPECT_EQ(c->request({{"cmd", "apply"}, {"confirm", true}, {"session", "nope"}})["error"]["code"],
            "not_found");
  EXPECT_EQ(c->call("apply", {{"confirm", true}})["session"], "20261122-0000");
  EXPECT_EQ(session_.applyCalls(), 1);
  EXPECT_EQ(c->call("status")["status"]["state"], "applying");
}

TEST_F(ControlServerTest, ApplyEventsAreSerialisedByTheControlLayer) {
  auto watcher = connect();
  watcher->call("subscribe");
  service::ApplyEvent done;
  done.session = "20261122-0000";
  done.outcome = service::ApplyOutcome::kRolledBack;
  done.message = "delta3 doubled: the sign of joint 3's transmission is wrong";
  done.verification = "20261122-0002";
  done.before_rad = {1, 2, 3, 4, 5, 6};
  done.written_rad = {1, 2.5, 3, 4, 5, 6};
  done.remaining_deg = {0.001, 1.1, -0.002, 0.0005};
  done.remaining_sigma_deg = {0.003, 0.001, 0.001, 0.001};
  session_.emit(service::ApplyProgressEvent{"20261122-0000", "written: rob1_2 2.500000"});
  session_.emit(done);
  std::optional<json> progress, outcome;
  const auto deadline = std::chrono::steady_clock::now() + 2s;
  while (!outcome && std::chrono::steady_clock::now() < deadline) {
    auto e = watcher->nextEvent(500ms);
    if (!e) continue;
    if ((*e)["event"] == "apply_progress") progress = e;
    if ((*e)["event"] == "apply") outcome = e;
  }
  ASSERT_TRUE(progress && outcome);
  EXPECT_EQ((*progress)["message"], "written: rob1_2 2.500000");
  EXPECT_EQ((*outcome)["outcome"], "rolled_back");
  EXPECT_EQ((*outcome)["written_rad"][1], 2.5);
  EXPECT_EQ((*outcome)["verification"], "20261122-0002");
  EXPECT_EQ((*outcome)["remaining_deg"]["delta3_deg"]["value"], 1.1);
}

TEST_F(ControlServerTest, Sessions) {
  const auto r = connect()->call("sessions");
  const auto list = r["sessions"];
  ASSERT_EQ(list.size(), 2u);  // newest first
  EXPECT_EQ(list[0]["id"], "20261122-0001");
  EXPECT_EQ(list[0]["recorded_poses"], 3);
  EXPECT_EQ(list[1]["finished"], true);
  EXPECT_EQ(r["total"], 2);
  EXPECT_FALSE(r.contains("next"));
}

// A large archive, and a small output limit: the answer is paged, and one page is never held
// against the limit that drops clients who do not read their events.
TEST_F(ControlServerTest, SessionsArePagedNewestFirst) {
  ServerOptions options;
  options.max_queued_bytes = 64 * 1024;
  startServer(options);
  session_.session_list.clear();
  for (int i = 0; i < 20000; ++i)
    session_.session_list.push_back(SessionInfo{fmt::format("20261122-{:05d}", i),
                                                fmt::format("/var/lib/zerocal/sessions/{}", i),
                                                i % 3 == 0, 8, 8, 0, ""});
  auto c = connect();
  // An old client's request, without paging: the newest 100 and where to go on.
  const auto first = c->call("sessions");
  ASSERT_EQ(first["sessions"].size(), 100u);
  EXPECT_EQ(first["sessions"][0]["id"], "20261122-19999");
  EXPECT_EQ(first["sessions"][99]["id"], "20261122-19900");
  EXPECT_EQ(first["next"], "20261122-19900");
  EXPECT_EQ(first["total"], 20000);
  // Every page of 1000 (over 100 KiB, above this limit) in turn: each session once, newest first.
  std::vector<std::string> ids;
  json cursor = nullptr;
  int pages = 0;
  do {
    json members{{"limit", 1000}};
    if (!cursor.is_null()) members["cursor"] = cursor;
    const auto page = c->call("sessions", members);
    EXPECT_GT(page.dump().size(), options.max_queued_bytes);
    for (const auto& s : page["sessions"]) ids.push_back(s["id"]);
    cursor = page.contains("next") ? page["next"] : json(nullptr);
    ++pages;
  } while (!cursor.is_null() && pages < 100);
  EXPECT_EQ(pages, 20);
  ASSERT_EQ(ids.size(), 20000u);
  EXPECT_TRUE(std::is_sorted(ids.rbegin(), ids.rend()));
  EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end());
  const auto bad = c->request({{"cmd", "sessions"}, {"limit", 0}});
  EXPECT_EQ(bad["error"]["code"], "bad_request");
  EXPECT_THAT(bad["error"]["message"].get<std::string>(), HasSubstr("limit: 0 is outside 1..1000"));
  EXPECT_EQ(c->request({{"cmd", "sessions"}, {"limit", "10"}})["error"]["code"], "bad_request");
  EXPECT_EQ(connections(), 1u);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, Result) {
  auto c = connect();
  EXPECT_EQ(c->call("result")["result"]["converged"], true);
  EXPECT_EQ(c->request({{"cmd", "result"}, {"session", "x"}})["error"]["code"], "not_found");
}

TEST_F(ControlServerTest, SubscribeForwardsSessionEventsAndPollsStatusWhileActive) {
  auto watcher = connect();
  EXPECT_EQ(watcher->call("subscribe")["status"]["state"], "idle");
  auto other = connect();
  other->call("start");
  session_.setState(SessionState::kServoing, 2, 8);
  session_.emit(testing::measuredPose(2, 1.5));
  bool saw_state = false, saw_pose = false, saw_status = false;
  const auto deadline = std::chrono::steady_clock::now() + 2s;
  while (!(saw_state && saw_pose && saw_status) && std::chrono::steady_clock::now() < deadline) {
    auto e = watcher->nextEvent(500ms);
    if (!e) continue;
    if ((*e)["event"] == "state" && (*e)["state"] == "servoing") saw_state = true;
    if ((*e)["event"] == "pose") saw_pose = (*e)["servo_error_um"] == 1.5;
    if ((*e)["event"] == "status") saw_status = (*e)["status"]["pose"] == 2;
  }
  EXPECT_TRUE(saw_state);
  EXPECT_TRUE(saw_pose);
  EXPECT_TRUE(saw_status);
  // Not subscribed: no events.
  EXPECT_EQ(other->nextEvent(200ms), std::nullopt);
  watcher->call("unsubscribe");
  while (watcher->nextEvent(100ms)) {
  }
  session_.emit(testing::measuredPose(3, 0));
  EXPECT_EQ(watcher->nextEvent(200ms), std::nullopt);
}

TEST_F(ControlServerTest, PsdAnswersWhenTheReadingArrives) {
  auto c = connect();
  const auto r = c->call("psd");
  EXPECT_DOUBLE_EQ(r["reading"]["u_mm"].get<double>(), 0.012);
  EXPECT_EQ(r["reading"]["spot_present"], true);
  session_.psd_fails = true;
  const auto e = c->request({{"cmd", "psd"}});
  EXPECT_EQ(e["error"]["code"], "unavailable");
  EXPECT_THAT(e["error"]["message"].get<std::string>(), HasSubstr("USB-1408FS"));
}

TEST_F(ControlServerTest, PlanPreviewsWithoutStarting) {
  auto c = connect();
  const auto r = c->call("plan", {{"poses", 9}, {"plan", "mixed"}});
  EXPECT_EQ(r["plan"]["poses"].size(), 9u);
  EXPECT_EQ(r["plan"]["rank"], 11);
  EXPECT_EQ(session_.startCalls(), 0);
  EXPECT_EQ(c->request({{"cmd", "plan"}, {"poses", 3}})["error"]["code"], "bad_request");
}

TEST_F(ControlServerTest, StatusStaysFastWhileAPlanIsComputed) {
  session_.preview_time = 600ms;
  auto planner = connect();
  planner->sendRaw(toLine({{"id", 1}, {"cmd", "plan"}}));
  std::this_thread::sleep_for(50ms);  // the preview is running now
  auto c = connect();
  for (int i = 0; i < 20; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    c->call("status");
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 50ms);
  }
  const auto r = json::parse(*planner->readLine(3s));
  EXPECT_EQ(r["ok"], true);
}

// A start plans for about a second before it answers: the others are answered meanwhile.
TEST_F(ControlServerTest, StatusStaysFastWhileAStartPlans) {
  session_.start_time = 600ms;
  auto starter = connect();
  starter->sendRaw(toLine({{"id", 1}, {"cmd", "start"}}));
  std::this_thread::sleep_for(50ms);  // the start is planning now
  auto c = connect();
  for (int i = 0; i < 20; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    c->call("status");
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 50ms);
  }
  const auto r = json::parse(*starter->readLine(3s));
  EXPECT_EQ(r["ok"], true);
  EXPECT_EQ(r["id"], 1);
  EXPECT_EQ(r["session"], "20261122-0001");
}

// -- bad input ---------------------------------------------------------------------------------

TEST_F(ControlServerTest, MalformedJsonIsAnsweredAndTheConnectionGoesOn) {
  auto c = connect();
  c->sendRaw("{\"cmd\": \"status\",,}\n");
  const auto r = json::parse(*c->readLine(1s));
  EXPECT_EQ(r["error"]["code"], "bad_json");
  EXPECT_TRUE(r["id"].is_null());
  c->sendRaw("[1,2,3]\n");
  EXPECT_EQ(json::parse(*c->readLine(1s))["error"]["code"], "bad_request");
  EXPECT_EQ(c->call("status")["ok"], true);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, UnknownCommand) {
  auto c = connect();
  const auto r = c->request({{"cmd", "self_destruct"}});
  EXPECT_EQ(r["error"]["code"], "unknown_command");
  EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("self_destruct"));
  expectOthersServedFast();
}

TEST_F(ControlServerTest, WrongTypesAreBadRequestsNamingTheMember) {
  auto c = connect();
  const std::vector<std::pair<json, std::string>> cases{
      {{{"cmd", 5}}, "cmd"},
      {{{"cmd", "start"}, {"poses", "8"}}, "poses"},
      {{{"cmd", "start"}, {"poses", 8.5}}, "poses"},
      {{{"cmd", "start"}, {"poses", -1}}, "poses"},
      {{{"cmd", "start"}, {"plan", 2}}, "plan"},
      {{{"cmd", "start"}, {"plan", "III"}}, "plan"},
      {{{"cmd", "start"}, {"target_mm", {1, 2}}}, "target_mm"},
      {{{"cmd", "start"}, {"target_mm", "900 0 400"}}, "target_mm"},
      {{{"cmd", "start"}, {"noise_mm", -1}}, "noise_mm"},
      {{{"cmd", "start"}, {"even_if_not_usable", 1}}, "even_if_not_usable"},
      {{{"cmd", "start"}, {"kind", "verification"}}, "kind"},
      {{{"cmd", "start"}, {"kind", 3}}, "kind"},
      {{{"cmd", "start"}, {"reference", "20261121T060000Z"}}, "reference"},
      {{{"cmd", "start"}, {"kind", "check"}, {"reference", 5}}, "reference"},
      {{{"cmd", "start"}, {"pose", 8}}, "pose"},
      {{{"cmd", "plan"}, {"poses", json::object()}}, "poses"},
      {{{"cmd", "result"}, {"session", 12}}, "session"},
      {{{"cmd", "resume"}, {"session", {1}}}, "session"},
      {{{"cmd", "auth"}, {"token", kToken}, {"id", 1}}, ""},
  };
  for (const auto& [request, member] : cases) {
    const auto r = c->request(request);
    if (member.empty()) continue;
    EXPECT_EQ(r["error"]["code"], "bad_request") << request.dump();
    EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr(member)) << request.dump();
  }
  EXPECT_EQ(session_.startCalls(), 0);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, AnOverLongLineIsRefusedAndClosed) {
  ServerOptions options;
  options.max_line_bytes = 1024;
  startServer(options);
  auto c = connect();
  c->sendRaw("{\"cmd\":\"status\",\"pad\":\"" + std::string(4096, 'x') + "\"}\n");
  const auto r = json::parse(*c->readLine(1s));
  EXPECT_EQ(r["error"]["code"], "line_too_long");
  expectClosed(*c);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, TheDefaultLineLimitIs64KiB) {
  auto c = connect();
  // Just under: a (bad) request, answered; just over: refused and closed.
  c->sendRaw("{\"cmd\":\"status\",\"pad\":\"" + std::string(60000, 'x') + "\"}\n");
  EXPECT_EQ(json::parse(*c->readLine(1s))["ok"], true);
  c->sendRaw(std::string(70000, 'x'));
  EXPECT_EQ(json::parse(*c->readLine(1s))["error"]["code"], "line_too_long");
  expectClosed(*c);
}

TEST_F(ControlServerTest, BinaryGarbage) {
  std::mt19937 random(7);
  std::string garbage(8192, '\0');
  for (auto& ch : garbage) ch = static_cast<char>(random());
  auto c = connect(false);
  c->sendRaw(garbage + "\n");
  // Every newline in the garbage ends a line, each answered with an error; then it goes on.
  int answers = 0;
  while (auto line = c->readLine(300ms)) {
    const auto r = json::parse(*line);  // our answers are valid JSON whatever came in
    EXPECT_EQ(r["ok"], false);
    ++answers;
  }
  EXPECT_GT(answers, 0);
  EXPECT_EQ(c->call("version")["ok"], true);
  // Invalid UTF-8 inside a string is refused too, not echoed into the answer.
  c->sendRaw("{\"cmd\":\"\xff\xfe\"}\n");
  EXPECT_EQ(json::parse(*c->readLine(1s))["error"]["code"], "bad_json");
  expectOthersServedFast();
}

TEST_F(ControlServerTest, HalfOpenAndTricklingConnectionsAreClosedWhenIdle) {
  ServerOptions options;
  options.idle_timeout = 300ms;
  startServer(options);
  auto silent = connect(false);
  auto trickling = connect(false);
  auto watcher = connect();
  watcher->call("subscribe");
  try {
    for (int i = 0; i < 6; ++i) {  // a line that never ends, a byte at a time
      trickling->sendRaw("{");
      std::this_thread::sleep_for(100ms);
    }
  } catch (const ConnectionError&) {  // closed while trickling: what is expected
  }
  const auto bye = json::parse(*silent->readLine(1s));
  EXPECT_EQ(bye["event"], "closing");
  expectClosed(*silent);
  expectClosed(*trickling);
  // A subscriber is quiet by design and stays.
  EXPECT_EQ(watcher->call("status")["ok"], true);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, ASubscriberThatDoesNotReadIsDropped) {
  ServerOptions options;
  options.max_queued_bytes = 256 * 1024;
  startServer(options);
  // A client with a small receive window that subscribes and then never reads.
  boost::asio::ip::tcp::socket slow(io_);
  slow.open(boost::asio::ip::tcp::v4());
  slow.set_option(boost::asio::socket_base::receive_buffer_size(4096));
  slow.connect({boost::asio::ip::make_address("127.0.0.1"), server_->port()});
  const std::string hello =
      toLine({{"cmd", "auth"}, {"token", kToken}}) + toLine({{"cmd", "subscribe"}});
  boost::asio::write(slow, boost::asio::buffer(hello));
  auto watcher = connect();
  watcher->call("subscribe");
  std::this_thread::sleep_for(50ms);  // the slow one's subscribe is handled
  session_.setState(SessionState::kServoing, 1, 8);
  const std::string filler(10000, 'x');
  int seen = -1;
  for (int i = 0; i < 1000; ++i) {
    service::PoseEvent big = testing::measuredPose(i, 0);
    big.record.skipped = filler;  // a long line
    session_.emit(big);
    // The reading watcher keeps up (so only the slow one's queue grows).
    while (i % 20 == 19 && seen < i) {
      auto e = watcher->nextEvent(1s);
      ASSERT_TRUE(e);
      if ((*e)["event"] == "pose") seen = (*e)["pose"];
    }
  }
  EXPECT_EQ(seen, 999);
  EXPECT_EQ(connections(), 1u);  // only the watcher is left
  EXPECT_EQ(watcher->call("status")["status"]["state"], "servoing");
  expectOthersServedFast();
}

TEST_F(ControlServerTest, ClientsBeyondTheLimitArePolitelyRefused) {
  ServerOptions options;
  options.max_clients = 4;
  startServer(options);
  std::vector<std::unique_ptr<ControlClient>> clients;
  for (int i = 0; i < 4; ++i) clients.push_back(connect());
  ControlClient extra;
  extra.connect("127.0.0.1", server_->port());
  const auto r = json::parse(*extra.readLine(1s));
  EXPECT_EQ(r["error"]["code"], "too_many_clients");
  expectClosed(extra);
  for (auto& c : clients) EXPECT_EQ(c->call("status")["ok"], true);
  clients.pop_back();  // one leaves: room for another
  const auto t0 = std::chrono::steady_clock::now();
  while (connections() > 3 && std::chrono::steady_clock::now() - t0 < 1s)
    std::this_thread::sleep_for(5ms);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, ManyConnectionsAtOnceLeaveTheSessionRunning) {
  session_.setState(SessionState::kMoving, 1, 8);
  std::vector<std::unique_ptr<ControlClient>> clients;
  for (int i = 0; i < 40; ++i) {
    clients.push_back(std::make_unique<ControlClient>());
    clients.back()->connect("127.0.0.1", server_->port());
  }
  for (auto& c : clients) c->sendRaw("garbage\n");
  clients.clear();  // all gone at once, some with answers unread
  expectOthersServedFast();
  EXPECT_EQ(session_.status().state, SessionState::kMoving);
  EXPECT_EQ(session_.abortCalls(), 0);
}

// -- hostile clients ---------------------------------------------------------------------------

TEST_F(ControlServerTest, ConnectionsThatNeverAuthenticateCannotLockOutAnAbort) {
  ServerOptions options;
  options.max_clients = 8;
  startServer(options);
  session_.setState(SessionState::kServoing, 2, 8);
  std::vector<std::unique_ptr<ControlClient>> strangers;
  for (int i = 0; i < 8; ++i) {
    strangers.push_back(connect(false));
    strangers.back()->sendRaw("\n");  // keeps it from looking idle
  }
  for (int attempt = 0; attempt < 5; ++attempt) {
    auto technician = connect();  // displaces the oldest stranger
    // The first abort stops the session; the later ones find nothing running, but get through.
    EXPECT_EQ(technician->call("abort")["aborted"], attempt == 0);
  }
  EXPECT_EQ(session_.abortCalls(), 5);
  EXPECT_LE(connections(), 8u);
  // The oldest stranger made room for the first technician (each later one took the slot its
  // predecessor left), and was told why before being closed.
  const auto why = strangers[0]->readLine(1s);
  ASSERT_TRUE(why.has_value());
  EXPECT_EQ(json::parse(*why)["error"]["code"], "too_many_clients");
  expectClosed(*strangers[0]);
}

TEST_F(ControlServerTest, EveryAuthenticatedSlotTakenRefusesTheNextClient) {
  ServerOptions options;
  options.max_clients = 3;
  startServer(options);
  std::vector<std::unique_ptr<ControlClient>> clients;
  for (int i = 0; i < 3; ++i) clients.push_back(connect());
  ControlClient extra;
  extra.connect("127.0.0.1", server_->port());
  EXPECT_EQ(json::parse(*extra.readLine(1s))["error"]["code"], "too_many_clients");
  for (auto& c : clients) EXPECT_EQ(c->call("status")["ok"], true);
}

TEST_F(ControlServerTest, AConnectionMustAuthenticateSoon) {
  ServerOptions options;
  options.auth_timeout = 200ms;
  startServer(options);
  auto stranger = connect(false);
  EXPECT_EQ(stranger->call("hello")["authenticated"], false);
  const auto line = stranger->readLine(2s);
  ASSERT_TRUE(line.has_value());
  EXPECT_EQ(json::parse(*line)["error"]["code"], "unauthenticated");
  expectClosed(*stranger);
  auto technician = connect();
  std::this_thread::sleep_for(400ms);
  EXPECT_EQ(technician->call("status")["ok"], true);  // authenticated: no deadline
}

TEST_F(ControlServerTest, ConnectionsPerPeerAreLimited) {
  ServerOptions options;
  options.max_clients = 8;
  options.max_clients_per_peer = 2;
  startServer(options);
  auto first = connect();
  auto second = connect();
  ControlClient third;
  third.connect("127.0.0.1", server_->port());
  const auto r = json::parse(*third.readLine(1s));
  EXPECT_EQ(r["error"]["code"], "too_many_clients");
  EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("from 127.0.0.1"));
  EXPECT_EQ(first->call("status")["ok"], true);
  // An unauthenticated connection of that peer makes room for it, as for the overall limit.
  first.reset();
  const auto t0 = std::chrono::steady_clock::now();
  while (connections() > 1 && std::chrono::steady_clock::now() - t0 < 1s)
    std::this_thread::sleep_for(5ms);
  auto stranger = connect(false);
  stranger->call("hello");  // the server has taken it in
  auto technician = connect();
  EXPECT_EQ(technician->call("status")["ok"], true);
  // The displaced connection is told why before it is closed.
  const auto why = stranger->readLine(1s);
  ASSERT_TRUE(why.has_value());
  const auto e = json::parse(*why);
  EXPECT_EQ(e["id"], nullptr);
  EXPECT_EQ(e["error"]["code"], "too_many_clients");
  EXPECT_THAT(e["error"]["message"].get<std::string>(),
              HasSubstr("closed to make room for a new connection: 2 connections from 127.0.0.1 "
                        "are open and this one has not authenticated"));
  expectClosed(*stranger);
}

TEST_F(ControlServerTest, DeepNestingIsRefusedWhileParsingBeforeAnythingRecursesOverIt) {
  ServerOptions options;
  options.max_line_bytes = 4 << 20;
  startServer(options);
  auto c = connect(false);
  c->sendRaw(R"({"id":[[1]],"cmd":"hello"})"
             "\n");
  auto r = json::parse(*c->readLine(2s));
  EXPECT_EQ(r["id"], json::parse("[[1]]"));  // a shallow structured id is still echoed
  // Half a million levels: far beyond what a recursive copy or dump survives on a thread stack.
  const std::size_t depth = 500000;
  c->sendRaw(R"({"cmd":"hello","id":)" + std::string(depth, '[') + std::string(depth, ']') + "}\n");
  r = json::parse(*c->readLine(5s));
  EXPECT_EQ(r["error"]["code"], "bad_json");
  EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("nested deeper"));
  EXPECT_EQ(c->call("hello", {{"id", "a string id"}})["ok"], true);
  expectOthersServedFast();
}

TEST_F(ControlServerTest, PlanFilesComeOnlyFromThePlanFolder) {
  ServerOptions options;
  options.plan_dir = "/var/lib/zerocal/plans";
  startServer(options);
  auto c = connect();
  for (const char* name : {"/etc/shadow", "../token", "plans/../../x", ".hidden", "..", ""}) {
    const auto r = c->request({{"cmd", "plan"}, {"plan", "file"}, {"plan_file", name}});
    EXPECT_EQ(r["error"]["code"], "bad_request") << name;
    EXPECT_THAT(r["error"]["message"].get<std::string>(), HasSubstr("plan folder")) << name;
  }
  EXPECT_EQ(session_.startCalls(), 0);
  c->call("start", {{"plan", "file"}, {"plan_file", "cell7.csv"}});
  EXPECT_EQ(session_.lastRequest().plan_file, "/var/lib/zerocal/plans/cell7.csv");

  options.plan_dir = "";
  startServer(options);
  auto d = connect();
  const auto r = d->request({{"cmd", "plan"}, {"plan", "file"}, {"plan_file", "cell7.csv"}});
  EXPECT_EQ(r["error"]["code"], "bad_request");
}

TEST_F(ControlServerTest, StopClosesEveryConnection) {
  auto c = connect();
  c->call("subscribe");
  stopServer();
  expectClosed(*c);
}

}  // namespace
}  // namespace zerocal::control
