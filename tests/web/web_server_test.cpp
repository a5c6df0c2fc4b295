// The web terminal's server over real sockets on loopback, beside the TCP control port on one hub
// with FakeSession behind it: the page files, the login and its cookie, the WebSocket carrying the
// protocol, and each class of bad input, each followed by a check that the daemon still serves.
#include "zerocal/web/web_server.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

#include "fake_session.h"
#include "zerocal/control/client.h"
#include "zerocal/control/line_connection.h"
#include "zerocal/control/messages.h"
#include "zerocal/control/server.h"
#include "zerocal/error.h"

namespace zerocal::web {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace fs = std::filesystem;
using asio::ip::tcp;
using nlohmann::json;
using namespace std::chrono_literals;
using ::testing::HasSubstr;

constexpr const char* kToken = "c0ffee-7451-secret-web";
constexpr const char* kOperatorToken = "operator-7451-checks-only";
using Reply = http::response<http::string_body>;

// A blocking client socket (Asio's blocking reads poll without a timeout: a daemon that never
// answers shows as the test's timeout).
tcp::socket connectTo(asio::io_context& io, std::uint16_t port) {
  tcp::socket socket(io);
  socket.connect({asio::ip::make_address("127.0.0.1"), port});
  return socket;
}

class WebServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("zerocal-web-" + std::to_string(::getpid()) + "-" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(root_ / "sub");
    std::ofstream(root_ / "index.html") << "<!doctype html><title>zerocal</title>";
    std::ofstream(root_ / "app.js") << "export const x = 1;";
    std::ofstream(root_ / "sub" / "style.css") << "body{}";
    std::ofstream(root_ / ".hidden") << "hidden";
    std::ofstream(root_.parent_path() / ("zerocal-web-outside-" + std::to_string(::getpid())))
        << "outside";
    fs::create_symlink(root_.parent_path() / ("zerocal-web-outside-" + std::to_string(::getpid())),
                       root_ / "escape.txt");
    options_.root = root_.string();
    // A sessions folder beside it: one session with its reports, one whose report is a link to
    // the file outside, and a result.json, which is not served.
    sessions_ = root_.string() + "-sessions";
    fs::create_directories(sessions_ / kSession);
    std::ofstream(sessions_ / kSession / "report.html") << "<!doctype html><p>report of it</p>";
    std::ofstream(sessions_ / kSession / "summary.txt") << "summary of it";
    std::ofstream(sessions_ / kSession / "result.json") << "{}";
    fs::create_directories(sessions_ / kLinkedSession);
    fs::create_symlink(root_.parent_path() / ("zerocal-web-outside-" + std::to_string(::getpid())),
                       sessions_ / kLinkedSession / "report.html");
    options_.sessions_dir = sessions_.string();
    options_.port = 0;
    start();
  }

  void start() {
    control::ServerOptions control;
    control.port = 0;
    control.token = kToken;
    control.operator_token = kOperatorToken;
    control.auth_failure_delay = 200ms;
    control.status_period = 50ms;
    hub_ = control::ProtocolHub::create(io_, session_, control);
    tcp_ = std::make_unique<control::ControlServer>(hub_);
    tcp_->start();
    web_ = std::make_unique<WebServer>(io_, hub_, options_);
    web_->start();
    io_.restart();
    thread_ = std::thread([this] {
      auto guard = asio::make_work_guard(io_);
      io_.run();
    });
  }

  void stop() {
    if (!thread_.joinable()) return;
    std::promise<void> stopped;
    asio::post(io_, [&] {
      web_->stop();
      tcp_->stop();
      hub_->stop();
      stopped.set_value();
    });
    stopped.get_future().wait();
    io_.stop();
    thread_.join();
    web_.reset();
    tcp_.reset();
    hub_.reset();
  }

  void TearDown() override {
    stop();
    std::error_code ec;
    fs::remove_all(root_, ec);
    fs::remove_all(sessions_, ec);
    fs::remove(root_.parent_path() / ("zerocal-web-outside-" + std::to_string(::getpid())), ec);
  }

  std::string host() const { return "127.0.0.1:" + std::to_string(web_->port()); }
  std::string origin() const { return "http://" + host(); }

  Reply request(http::verb verb, const std::string& target, const std::string& body = {},
                const std::string& cookie = {}, const std::string& origin = {}) {
    asio::io_context io;
    auto socket = connectTo(io, web_->port());
    http::request<http::string_body> req{verb, target, 11};
    req.set(http::field::host, host());
    if (!cookie.empty()) req.set(http::field::cookie, cookie);
    if (!origin.empty()) req.set(http::field::origin, origin);
    if (!body.empty()) {
      req.set(http::field::content_type, "application/json");
      req.body() = body;
    }
    req.prepare_payload();
    http::write(socket, req);
    beast::flat_buffer buffer;
    Reply reply;
    http::read(socket, buffer, reply);
    return reply;
  }

  // What an upgrade to the WebSocket is answered, as a browser would ask it.
  http::status upgradeStatus(const std::string& cookie, const std::string& origin) {
    asio::io_context io;
    auto socket = connectTo(io, web_->port());
    http::request<http::string_body> req{http::verb::get, "/ws", 11};
    req.set(http::field::host, host());
    req.set(http::field::upgrade, "websocket");
    req.set(http::field::connection, "Upgrade");
    req.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
    req.set(http::field::sec_websocket_version, "13");
    if (!cookie.empty()) req.set(http::field::cookie, cookie);
    if (!origin.empty()) req.set(http::field::origin, origin);
    http::write(socket, req);
    beast::flat_buffer buffer;
    http::response<http::empty_body> reply;
    http::response_parser<http::empty_body> parser;
    parser.skip(true);  // a 101 has no body; a refusal's is not needed
    http::read_header(socket, buffer, parser);
    return parser.get().result();
  }

  // The cookie's "name=value", from a login with the right token.
  std::string login(const std::string& token = kToken) {
    const Reply r = request(http::verb::post, "/api/login", json{{"token", token}}.dump());
    EXPECT_EQ(r.result(), http::status::ok) << r.body();
    const std::string set(r[http::field::set_cookie]);
    return set.substr(0, set.find(';'));
  }

  // A WebSocket to /ws; the handshake's response in `reply` (an upgrade refused throws).
  std::unique_ptr<websocket::stream<tcp::socket>> openWs(asio::io_context& io,
                                                         const std::string& cookie,
                                                         const std::string& origin,
                                                         websocket::response_type& reply) {
    auto ws = std::make_unique<websocket::stream<tcp::socket>>(connectTo(io, web_->port()));
    ws->set_option(websocket::stream_base::decorator([cookie, origin](websocket::request_type& r) {
      if (!cookie.empty()) r.set(http::field::cookie, cookie);
      if (!origin.empty()) r.set(http::field::origin, origin);
    }));
    ws->handshake(reply, host(), "/ws");
    return ws;
  }

  // A WebSocket of a fresh login, from the terminal's own page.
  std::unique_ptr<websocket::stream<tcp::socket>> openLoggedIn(asio::io_context& io) {
    websocket::response_type reply;
    return openWs(io, login(), origin(), reply);
  }

  static json wsCall(websocket::stream<tcp::socket>& ws, const json& request) {
    ws.write(asio::buffer(request.dump()));
    for (;;) {
      beast::flat_buffer buffer;
      ws.read(buffer);
      const json line = json::parse(beast::buffers_to_string(buffer.data()));
      if (!line.contains("event")) return line;
    }
  }

  static json wsRead(websocket::stream<tcp::socket>& ws) {
    beast::flat_buffer buffer;
    ws.read(buffer);
    return json::parse(beast::buffers_to_string(buffer.data()));
  }

  // A TCP client gets its status answer quickly: the daemon was not hurt.
  void expectOthersServedFast() {
    control::ControlClient c;
    c.connect("127.0.0.1", tcp_->port());
    c.authenticate(kToken);
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_TRUE(c.call("status")["status"].is_object());
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 100ms);
    EXPECT_EQ(request(http::verb::get, "/").result(), http::status::ok);
  }

  std::size_t hubConnections() {
    std::promise<std::size_t> n;
    asio::post(io_, [&] { n.set_value(hub_->connectionCount()); });
    return n.get_future().get();
  }

  static constexpr const char* kSession = "20261122T073447Z";
  static constexpr const char* kLinkedSession = "20261122T073447Z-002";
  fs::path root_;
  fs::path sessions_;
  WebOptions options_;
  asio::io_context io_;
  control::testing::FakeSession session_;
  std::shared_ptr<control::ProtocolHub> hub_;
  std::unique_ptr<control::ControlServer> tcp_;
  std::unique_ptr<WebServer> web_;
  std::thread thread_;
};

TEST_F(WebServerTest, ServesThePageFilesWithTheirTypesAndNothingFromElsewhere) {
  const Reply index = request(http::verb::get, "/");
  EXPECT_EQ(index.result(), http::status::ok);
  EXPECT_THAT(index.body(), HasSubstr("<title>zerocal</title>"));
  EXPECT_EQ(index[http::field::content_type], "text/html; charset=utf-8");
  EXPECT_THAT(std::string(index["Content-Security-Policy"]), HasSubstr("default-src 'self'"));
  EXPECT_EQ(request(http::verb::get, "/app.js")[http::field::content_type],
            "text/javascript; charset=utf-8");
  EXPECT_EQ(request(http::verb::get, "/sub/style.css?v=2").body(), "body{}");
}

TEST_F(WebServerTest, UnknownPathsAre404AndOtherMethods405) {
  EXPECT_EQ(request(http::verb::get, "/nothing.html").result(), http::status::not_found);
  EXPECT_EQ(request(http::verb::get, "/sub").result(), http::status::not_found);  // a folder
  EXPECT_EQ(request(http::verb::delete_, "/index.html").result(), http::status::method_not_allowed);
  EXPECT_EQ(request(http::verb::get, "/api/logout").result(), http::status::method_not_allowed);
  expectOthersServedFast();
}

TEST_F(WebServerTest, PathTraversalIsRefusedBeforeTheFileSystemIsAsked) {
  for (const char* path :
       {"/../index.html", "/sub/../../etc/passwd", "/%2e%2e/etc/passwd", "/.hidden", "//etc/passwd",
        "/sub/./style.css", "/a\\b", "/index.html%00.js"}) {
    const Reply r = request(http::verb::get, path);
    EXPECT_EQ(r.result(), http::status::bad_request) << path;
    EXPECT_THAT(r.body(), ::testing::Not(HasSubstr("root:")));
  }
  // A link inside the folder that leads out of it is no page.
  const Reply escape = request(http::verb::get, "/escape.txt");
  EXPECT_EQ(escape.result(), http::status::not_found);
  EXPECT_THAT(escape.body(), ::testing::Not(HasSubstr("outside")));
  expectOthersServedFast();
}

TEST_F(WebServerTest, ASessionsReportsAreServedToALoggedInBrowserOnly) {
  const std::string report = std::string("/sessions/") + kSession + "/report.html";
  const std::string summary = std::string("/sessions/") + kSession + "/summary.txt";
  // Without a login (or with a login forgotten) nothing of a session is told.
  for (const std::string& cookie : {std::string(), std::string("zerocal_login=0123")}) {
    const Reply r = request(http::verb::get, report, {}, cookie);
    EXPECT_EQ(r.result(), http::status::unauthorized) << cookie;
    EXPECT_THAT(r.body(), ::testing::Not(HasSubstr("report of it")));
  }
  const std::string cookie = login();
  const Reply html = request(http::verb::get, report, {}, cookie);
  ASSERT_EQ(html.result(), http::status::ok);
  EXPECT_EQ(html.body(), "<!doctype html><p>report of it</p>");
  EXPECT_EQ(html[http::field::content_type], "text/html; charset=utf-8");
  // Its own inline styles and nothing else: no script runs in it.
  const std::string policy(html["Content-Security-Policy"]);
  EXPECT_THAT(policy, HasSubstr("default-src 'none'"));
  EXPECT_THAT(policy, HasSubstr("sandbox"));
  EXPECT_THAT(policy, ::testing::Not(HasSubstr("script-src")));
  const Reply text = request(http::verb::get, summary + "?v=1", {}, cookie);
  EXPECT_EQ(text.result(), http::status::ok);
  EXPECT_EQ(text.body(), "summary of it");
  EXPECT_EQ(text[http::field::content_type], "text/plain; charset=utf-8");
  // The other files of the folder, and sessions that are not there, are not found.
  for (const std::string& path : {std::string("/sessions/") + kSession + "/result.json",
                                  std::string("/sessions/") + kSession + "/report.htm",
                                  std::string("/sessions/20261122T000000Z/report.html")}) {
    EXPECT_EQ(request(http::verb::get, path, {}, cookie).result(), http::status::not_found) << path;
  }
  expectOthersServedFast();
}

TEST_F(WebServerTest, AReportPathLeadingOutOfTheSessionsFolderIsRefused) {
  const std::string cookie = login();
  for (const char* path :
       {"/sessions/../index.html", "/sessions/..%2findex.html", "/sessions/%2e%2e/x/report.html",
        "/sessions/20261122T073447Z/../../etc/passwd", "/sessions/20261122T073447Z/./report.html",
        "/sessions/20261122T073447Z/.hidden", "/sessions//report.html",
        "/sessions/20261122t073447z/report.html", "/sessions/2026112xT073447Z/report.html",
        "/sessions/20261122T073447Z-02/report.html", "/sessions/20261122T073447Z%00/report.html",
        "/sessions/20261122T073447Z\\..\\report.html", "/sessions/etc/passwd",
        "/sessions/20261122T073447Z/report.html/x", "/sessions/20261122T073447Z"}) {
    const Reply r = request(http::verb::get, path, {}, cookie);
    EXPECT_EQ(r.result(), http::status::bad_request) << path;
    EXPECT_THAT(r.body(), ::testing::Not(HasSubstr("root:")));
  }
  // A report that is a link to a file outside the sessions folder is not served.
  const Reply linked = request(
      http::verb::get, std::string("/sessions/") + kLinkedSession + "/report.html", {}, cookie);
  EXPECT_EQ(linked.result(), http::status::not_found);
  EXPECT_THAT(linked.body(), ::testing::Not(HasSubstr("outside")));
  // Nor anything when the daemon names no sessions folder.
  stop();
  options_.sessions_dir.clear();
  start();
  EXPECT_EQ(
      request(http::verb::get, std::string("/sessions/") + kSession + "/report.html", {}, login())
          .result(),
      http::status::not_found);
  expectOthersServedFast();
}

TEST_F(WebServerTest, AWrongTokenIsRefusedAfterTheAuthFailureDelay) {
  const auto t0 = std::chrono::steady_clock::now();
  const Reply r = request(http::verb::post, "/api/login", json{{"token", "guess"}}.dump());
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 200ms);
  EXPECT_EQ(r.result(), http::status::unauthorized);
  EXPECT_TRUE(r[http::field::set_cookie].empty());
  const json body = json::parse(r.body());
  EXPECT_EQ(body["error"]["code"], "auth_failed");
  EXPECT_EQ(body["error"]["message"], "wrong token");
  for (const char* bad : {"", "{}", "[1]", "{\"token\":7}", "not json"})
    EXPECT_EQ(request(http::verb::post, "/api/login", bad).result(), http::status::unauthorized)
        << bad;
  expectOthersServedFast();
}

TEST_F(WebServerTest, TheTokenIsExchangedForAnHttpOnlyStrictCookieThatExpires) {
  const Reply r = request(http::verb::post, "/api/login", json{{"token", kToken}}.dump());
  ASSERT_EQ(r.result(), http::status::ok);
  const std::string set(r[http::field::set_cookie]);
  EXPECT_THAT(set, HasSubstr("HttpOnly"));
  EXPECT_THAT(set, HasSubstr("SameSite=Strict"));
  EXPECT_THAT(set, HasSubstr("Max-Age=28800"));  // the default lifetime, 8 h
  EXPECT_THAT(set, HasSubstr("Path=/"));
  const std::string cookie = set.substr(0, set.find(';'));
  EXPECT_GE(cookie.size(), std::string("zerocal_login=").size() + 32);  // 128 bits at least
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, cookie).result(), http::status::ok);
  EXPECT_EQ(request(http::verb::get, "/api/login").result(), http::status::unauthorized);
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, "zerocal_login=0123").result(),
            http::status::unauthorized);
  // A logout forgets it.
  EXPECT_EQ(request(http::verb::post, "/api/logout", {}, cookie).result(), http::status::ok);
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, cookie).result(),
            http::status::unauthorized);
}

TEST_F(WebServerTest, BeyondMaxLoginsTheOldestIsForgotten) {
  stop();
  options_.max_logins = 2;
  start();
  const std::string first = login(), second = login(), third = login();
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, first).result(), http::status::unauthorized);
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, second).result(), http::status::ok);
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, third).result(), http::status::ok);
}

TEST_F(WebServerTest, ALoginFromAnotherSitesPageIsRefused) {
  const Reply r = request(http::verb::post, "/api/login", json{{"token", kToken}}.dump(), {},
                          "http://evil.example");
  EXPECT_EQ(r.result(), http::status::forbidden);
  EXPECT_TRUE(r[http::field::set_cookie].empty());
}

TEST_F(WebServerTest, AnExpiredLoginOpensNoWebSocketAndClosesTheOpenOnes) {
  stop();
  options_.session_lifetime = 1500ms;
  start();
  const std::string cookie = login();
  asio::io_context io;
  websocket::response_type reply;
  auto ws = openWs(io, cookie, origin(), reply);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "subscribe"}})["ok"], true);
  std::this_thread::sleep_for(1600ms);
  EXPECT_EQ(request(http::verb::get, "/api/login", {}, cookie).result(),
            http::status::unauthorized);
  // Within the watchdog's second, the open one is told and closed.
  bool told = false;
  try {
    for (int i = 0; i < 40; ++i) {
      const json line = wsRead(*ws);
      if (line.value("event", "") == "closing") {
        told = true;
        EXPECT_THAT(line["reason"].get<std::string>(), HasSubstr("log in again"));
      }
    }
  } catch (const beast::system_error&) {
  }
  EXPECT_TRUE(told);
  websocket::response_type again;
  EXPECT_THROW(openWs(io, cookie, origin(), again), beast::system_error);
  EXPECT_EQ(upgradeStatus(cookie, origin()), http::status::unauthorized);
}

TEST_F(WebServerTest, AWebSocketWithoutAValidCookieOrFromAnotherOriginIsRefused) {
  const std::string cookie = login();
  asio::io_context io;
  struct Case {
    std::string cookie, origin;
    http::status expected;
  };
  for (const Case& c : {Case{"", origin(), http::status::unauthorized},
                        Case{"zerocal_login=feedfeedfeed", origin(), http::status::unauthorized},
                        Case{cookie, "http://evil.example", http::status::forbidden},
                        Case{cookie, "", http::status::forbidden},
                        Case{cookie, "http://127.0.0.1:1", http::status::forbidden}}) {
    websocket::response_type reply;
    EXPECT_THROW(openWs(io, c.cookie, c.origin, reply), beast::system_error)
        << c.cookie << " " << c.origin;
    EXPECT_EQ(upgradeStatus(c.cookie, c.origin), c.expected) << c.cookie << " " << c.origin;
  }
  EXPECT_EQ(upgradeStatus(cookie, origin()), http::status::switching_protocols);
  EXPECT_EQ(session_.startCalls(), 0);
  expectOthersServedFast();
}

TEST_F(WebServerTest, TheWebSocketCarriesTheControlProtocolAuthenticatedByTheCookie) {
  asio::io_context io;
  auto ws = openLoggedIn(io);
  const json hello = wsCall(*ws, {{"cmd", "hello"}, {"id", 1}});
  EXPECT_EQ(hello["id"], 1);
  EXPECT_EQ(hello["authenticated"], true);
  EXPECT_EQ(hello["protocol"], control::kProtocolVersion);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "status"}, {"id", 2}})["status"]["state"], "idle");
  // The same refusals as on the TCP port, word for word.
  control::ControlClient tcp;
  tcp.connect("127.0.0.1", tcp_->port());
  tcp.authenticate(kToken);
  for (const json& request :
       {json{{"cmd", "start"}, {"poses", "8"}}, json{{"cmd", "apply"}, {"session", "x"}},
        json{{"cmd", "launch"}}, json{{"cmd", "start"}, {"pose", 8}}}) {
    const json over_ws = wsCall(*ws, request);
    const json over_tcp = tcp.request(request);
    EXPECT_EQ(over_ws["ok"], false) << request;
    EXPECT_EQ(over_ws["error"], over_tcp["error"]) << request;
  }
  EXPECT_EQ(session_.applyCalls(), 0);  // not confirmed
  EXPECT_EQ(wsCall(*ws, {{"cmd", "abort"}})["aborted"], false);
  EXPECT_EQ(session_.abortCalls(), 1);
  // Garbage is answered and the WebSocket goes on.
  EXPECT_EQ(wsCall(*ws, json("not an object"))["error"]["code"], "bad_request");
  ws->write(asio::buffer(std::string("{nope")));
  EXPECT_EQ(wsRead(*ws)["error"]["code"], "bad_json");
  EXPECT_EQ(wsCall(*ws, {{"cmd", "version"}})["ok"], true);
}

TEST_F(WebServerTest, AnOperatorsLoginChecksAndAbortsButNeitherCalibratesNorWrites) {
  const Reply r = request(http::verb::post, "/api/login", json{{"token", kOperatorToken}}.dump());
  ASSERT_EQ(r.result(), http::status::ok);
  EXPECT_EQ(json::parse(r.body())["role"], "operator");
  const std::string set(r[http::field::set_cookie]);
  const std::string cookie = set.substr(0, set.find(';'));
  EXPECT_EQ(json::parse(request(http::verb::get, "/api/login", {}, cookie).body())["role"],
            "operator");
  asio::io_context io;
  websocket::response_type reply;
  auto ws = openWs(io, cookie, origin(), reply);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "hello"}})["role"], "operator");
  EXPECT_EQ(wsCall(*ws, {{"cmd", "status"}})["ok"], true);
  for (const json& request : {json{{"cmd", "start"}}, json{{"cmd", "start"}, {"kind", "restore"}},
                              json{{"cmd", "apply"}, {"session", "x"}, {"confirm", true}},
                              json{{"cmd", "verify"}, {"session", "x"}},
                              json{{"cmd", "acknowledge"}}, json{{"cmd", "resume"}}}) {
    const json answer = wsCall(*ws, request);
    EXPECT_EQ(answer["error"]["code"], "forbidden") << request << answer;
  }
  EXPECT_EQ(session_.startCalls(), 0);
  EXPECT_EQ(session_.applyCalls(), 0);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "start"}, {"kind", "check"}})["ok"], true);
  EXPECT_EQ(session_.startCalls(), 1);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "abort"}})["ok"], true);
  // The engineer's login may do all of it.
  auto engineer = openLoggedIn(io);
  EXPECT_EQ(wsCall(*engineer, {{"cmd", "hello"}})["role"], "engineer");
  EXPECT_NE(wsCall(*engineer, {{"cmd", "start"}, {"kind", "restore"}})["error"]["code"],
            "forbidden");
}

TEST_F(WebServerTest, OneEventSinkFansOutToBothTransports) {
  asio::io_context io;
  auto ws = openLoggedIn(io);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "subscribe"}})["ok"], true);
  control::ControlClient tcp;
  tcp.connect("127.0.0.1", tcp_->port());
  tcp.authenticate(kToken);
  tcp.call("subscribe");
  session_.emit(control::testing::measuredPose(3, 1.7));
  json from_ws;
  do from_ws = wsRead(*ws);
  while (from_ws.value("event", "") != "pose");
  EXPECT_EQ(from_ws["pose"], 3);
  const auto from_tcp = tcp.nextEvent(2000ms);
  ASSERT_TRUE(from_tcp);
  EXPECT_EQ(*from_tcp, from_ws);
}

TEST_F(WebServerTest, OversizedHeadersAndBodiesAreRefusedByBeastsLimits) {
  {
    asio::io_context io;
    auto socket = connectTo(io, web_->port());
    const std::string big =
        "GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n";
    boost::system::error_code ec;
    asio::write(socket, asio::buffer(big), ec);
    beast::flat_buffer buffer;
    Reply reply;
    http::read(socket, buffer, reply);
    EXPECT_EQ(reply.result(), http::status::request_header_fields_too_large);
  }
  const Reply body =
      request(http::verb::post, "/api/login", json{{"token", std::string(10000, 'k')}}.dump());
  EXPECT_EQ(body.result(), http::status::payload_too_large);
  expectOthersServedFast();
}

TEST_F(WebServerTest, GarbageAndSlowClientsDoNotTakeTheDaemonDown) {
  {
    asio::io_context io;
    auto socket = connectTo(io, web_->port());
    asio::write(socket, asio::buffer(std::string("\x16\x03\x01\x02\x00garbage\r\n\r\n", 16)));
    beast::flat_buffer buffer;
    Reply reply;
    http::read(socket, buffer, reply);
    EXPECT_EQ(reply.result(), http::status::bad_request);
  }
  // Half a request, then silence: others are served meanwhile.
  asio::io_context io;
  auto slow = connectTo(io, web_->port());
  asio::write(slow, asio::buffer(std::string("GET / HTTP/1.1\r\nHost: x\r\n")));
  expectOthersServedFast();
}

TEST_F(WebServerTest, AnOversizedWebSocketMessageClosesIt) {
  asio::io_context io;
  auto ws = openLoggedIn(io);
  ws->write(asio::buffer(std::string(70000, ' ')));
  // Beast closes a WebSocket whose message is over its limit itself, with 1009 "too big".
  EXPECT_THROW(wsRead(*ws), beast::system_error);
  EXPECT_EQ(ws->reason().code, websocket::close_code::too_big);
  expectOthersServedFast();
}

TEST_F(WebServerTest, StoppingClosesWebSocketsAndLeavesNoConnection) {
  asio::io_context io;
  auto ws = openLoggedIn(io);
  EXPECT_EQ(wsCall(*ws, {{"cmd", "status"}})["ok"], true);
  EXPECT_GE(hubConnections(), 1u);
  stop();
  EXPECT_THROW(wsRead(*ws), beast::system_error);
}

TEST(WebServerSetup, RefusesAnAddressOtherThanLoopbackUnlessTheNetworkIsTrusted) {
  asio::io_context io;
  control::testing::FakeSession session;
  control::ServerOptions control;
  control.token = kToken;
  auto hub = control::ProtocolHub::create(io, session, control);
  WebOptions options;
  options.bind_address = "0.0.0.0";
  options.root = ZEROCAL_SOURCE_DIR "/web";
  EXPECT_THAT([&] { WebServer(io, hub, options); },
              ::testing::ThrowsMessage<Error>(HasSubstr("no TLS")));
  options.trusted_network = true;
  EXPECT_NO_THROW(WebServer(io, hub, options));
  options.root = "/nonexistent";
  EXPECT_THAT([&] { WebServer(io, hub, options); },
              ::testing::ThrowsMessage<Error>(HasSubstr("no index.html")));
  hub->stop();
}

// A self-signed certificate for 127.0.0.1 and its key, made with the openssl command.
struct SelfSigned {
  SelfSigned() {
    dir = fs::temp_directory_path() / ("zerocal-web-tls-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::string command =
        "openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 "
        "-subj /CN=127.0.0.1 -addext subjectAltName=IP:127.0.0.1 -keyout " +
        key() + " -out " + certificate() + " 2>/dev/null";
    made = std::system(command.c_str()) == 0 && fs::exists(key()) && fs::exists(certificate());
  }
  ~SelfSigned() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string certificate() const { return (dir / "cert.pem").string(); }
  std::string key() const { return (dir / "key.pem").string(); }
  fs::path dir;
  bool made = false;
};

TEST_F(WebServerTest, WithACertificateEverythingIsServedOverTlsOnly) {
  const SelfSigned tls;
  ASSERT_TRUE(tls.made) << "the openssl command (Debian's openssl) made no certificate";
  stop();
  options_.tls_certificate = tls.certificate();
  options_.tls_key = tls.key();
  start();
  // The client trusts that certificate alone, and checks it.
  asio::io_context io;
  asio::ssl::context client(asio::ssl::context::tls_client);
  client.load_verify_file(tls.certificate());
  client.set_verify_mode(asio::ssl::verify_peer);
  const auto https = [&](http::verb verb, const std::string& target, const std::string& body,
                         const std::string& cookie) {
    beast::ssl_stream<tcp::socket> stream(connectTo(io, web_->port()), client);
    stream.handshake(asio::ssl::stream_base::client);
    http::request<http::string_body> req{verb, target, 11};
    req.set(http::field::host, host());
    req.set(http::field::origin, "https://" + host());
    if (!cookie.empty()) req.set(http::field::cookie, cookie);
    req.body() = body;
    req.prepare_payload();
    http::write(stream, req);
    beast::flat_buffer buffer;
    Reply reply;
    http::read(stream, buffer, reply);
    return reply;
  };
  const Reply index = https(http::verb::get, "/", {}, {});
  EXPECT_EQ(index.result(), http::status::ok);
  EXPECT_THAT(index.body(), HasSubstr("<title>zerocal</title>"));
  // The login cookie is Secure: a browser never sends it over plain HTTP.
  const Reply login = https(http::verb::post, "/api/login", json{{"token", kToken}}.dump(), {});
  ASSERT_EQ(login.result(), http::status::ok);
  const std::string set(login[http::field::set_cookie]);
  EXPECT_THAT(set, HasSubstr("; Secure"));
  const std::string cookie = set.substr(0, set.find(';'));
  EXPECT_EQ(
      https(http::verb::get, std::string("/sessions/") + kSession + "/summary.txt", {}, cookie)
          .body(),
      "summary of it");

  // The WebSocket over TLS (wss), from the terminal's https page only.
  const auto wss = [&](const std::string& origin) {
    auto ws = std::make_unique<websocket::stream<beast::ssl_stream<tcp::socket>>>(
        connectTo(io, web_->port()), client);
    ws->next_layer().handshake(asio::ssl::stream_base::client);
    ws->set_option(websocket::stream_base::decorator([&](websocket::request_type& r) {
      r.set(http::field::cookie, cookie);
      r.set(http::field::origin, origin);
    }));
    ws->handshake(host(), "/ws");
    return ws;
  };
  auto ws = wss("https://" + host());
  ws->write(asio::buffer(json{{"cmd", "status"}, {"id", 1}}.dump()));
  beast::flat_buffer buffer;
  ws->read(buffer);
  EXPECT_TRUE(json::parse(beast::buffers_to_string(buffer.data()))["status"].is_object());
  EXPECT_THROW(wss("http://" + host()), boost::system::system_error);  // another origin

  // Plain HTTP to the TLS port gets no page: the handshake fails and the connection closes.
  EXPECT_THROW(request(http::verb::get, "/"), boost::system::system_error);
  // Nor does a client that does not trust the certificate.
  asio::ssl::context other(asio::ssl::context::tls_client);
  other.set_verify_mode(asio::ssl::verify_peer);
  beast::ssl_stream<tcp::socket> untrusting(connectTo(io, web_->port()), other);
  EXPECT_THROW(untrusting.handshake(asio::ssl::stream_base::client), boost::system::system_error);
  // The TCP port and the TLS terminal still serve.
  EXPECT_EQ(https(http::verb::get, "/app.js", {}, {}).result(), http::status::ok);
}

TEST(WebServerSetup, TlsServesAnyAddressAndNeedsItsCertificateAndKey) {
  const SelfSigned tls;
  ASSERT_TRUE(tls.made) << "the openssl command (Debian's openssl) made no certificate";
  asio::io_context io;
  control::testing::FakeSession session;
  control::ServerOptions control;
  control.token = kToken;
  auto hub = control::ProtocolHub::create(io, session, control);
  WebOptions options;
  options.bind_address = "0.0.0.0";
  options.root = ZEROCAL_SOURCE_DIR "/web";
  options.tls_certificate = tls.certificate();
  options.tls_key = tls.key();
  EXPECT_NO_THROW(WebServer(io, hub, options));  // no trusted_network needed
  options.tls_key.clear();
  EXPECT_THAT([&] { WebServer(io, hub, options); },
              ::testing::ThrowsMessage<Error>(HasSubstr("go together")));
  options.tls_key = tls.certificate();  // not a key
  EXPECT_THAT([&] { WebServer(io, hub, options); },
              ::testing::ThrowsMessage<Error>(HasSubstr("web.tls_key")));
  options.tls_key = tls.key();
  options.tls_certificate = (tls.dir / "missing.pem").string();
  EXPECT_THAT([&] { WebServer(io, hub, options); },
              ::testing::ThrowsMessage<Error>(HasSubstr("web.tls_certificate")));
  hub->stop();
}

TEST(WebServerSetup, TheDefaultRootIsBesideTheProgram) {
  // The build tree has them there as the package does (build/bin/../share/zerocal/web).
  EXPECT_EQ(fs::path(defaultWebRoot()),
            (fs::path(ZEROCAL_BINARY_DIR) / "share/zerocal/web").lexically_normal());
  EXPECT_TRUE(fs::is_regular_file(fs::path(defaultWebRoot()) / "index.html"));
}

}  // namespace
}  // namespace zerocal::web
