// Load and latency of the web terminal (docs/web.md, "Load and latency"): `zerocald --sim` started
// here on a fresh data folder, N WebSocket clients (each logged in with the token, as N browsers)
// and one TCP client subscribed to its events, a reference session started, and meanwhile
// another TCP client asking `status` over and over. Prints:
//   - the `status` round trip on the TCP port (p50, p99, max; requirement p99 < 5 ms);
//   - each event's delay at each WebSocket client after it first arrived at any subscriber (the
//     daemon writes one line to every subscriber at once: the earliest arrival is the moment it
//     left the daemon plus a loopback hop; requirement within 100 ms);
//   - whether every client got every event, in order, the same bytes as the TCP subscriber.
// Exits 1 when a requirement (or --max-p99-ms, --max-event-ms) is missed or an event was lost.
//
//   build/bin/bench_web --zerocald build/bin/zerocald --clients 20 --pace 0.2
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>
#include <vector>

#include "zerocal/control/client.h"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace fs = std::filesystem;
using asio::ip::tcp;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

constexpr const char* kToken = "bench-web-token-0123456789";

double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0;
  return sorted[std::min(sorted.size() - 1, static_cast<std::size_t>(p * sorted.size()))];
}

// zerocald --sim on `dir`, its log in dir/zerocald.log; the two ports read from the log.
struct Daemon {
  pid_t pid = -1;
  std::uint16_t control_port = 0;
  std::uint16_t web_port = 0;

  Daemon(const std::string& zerocald, const fs::path& dir, double pace) {
    const fs::path token = dir / "token";
    std::ofstream(token) << kToken << "\n";
    fs::permissions(token, fs::perms::owner_read | fs::perms::owner_write);
    const fs::path log = dir / "zerocald.log";
    std::vector<std::string> args{zerocald,     "--sim",
                                  "--seed",     "1",
                                  "--config",   "/dev/null",
                                  "--data-dir", (dir / "sessions").string(),
                                  "--set",      "control.token_file=" + token.string(),
                                  "--set",      "control.port=0",
                                  "--set",      "web.port=0",
                                  "--set",      "backend.sim_pace=" + std::to_string(pace)};
    pid = ::fork();
    if (pid < 0) throw std::runtime_error("fork failed");
    if (pid == 0) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    const std::regex control_line(R"(control port listening on [0-9.]+:(\d+))");
    const std::regex web_line(R"(web terminal listening on http://[0-9.]+:(\d+)/)");
    const auto deadline = Clock::now() + 30s;
    while (Clock::now() < deadline && (control_port == 0 || web_port == 0)) {
      std::ifstream in(log);
      std::stringstream text;
      text << in.rdbuf();
      const std::string s = text.str();
      std::smatch m;
      if (std::regex_search(s, m, control_line)) control_port = std::stoi(m[1]);
      if (std::regex_search(s, m, web_line)) web_port = std::stoi(m[1]);
      int status = 0;
      if (::waitpid(pid, &status, WNOHANG) == pid) {
        pid = -1;
        throw std::runtime_error("zerocald stopped at its start:\n" + s);
      }
      std::this_thread::sleep_for(50ms);
    }
    if (control_port == 0 || web_port == 0)
      throw std::runtime_error("zerocald named no ports in " + log.string());
  }

  ~Daemon() {
    if (pid <= 0) return;
    ::kill(pid, SIGTERM);
    int status = 0;
    ::waitpid(pid, &status, 0);
  }
};

// What one subscriber received: each line and when.
struct Arrivals {
  std::vector<std::string> lines;
  std::vector<Clock::time_point> times;
  void add(std::string line) {
    times.push_back(Clock::now());
    lines.push_back(std::move(line));
  }
};

// The login cookie ("zerocal_login=..."), as a browser gets it: POST /api/login.
std::string logIn(asio::io_context& io, std::uint16_t port) {
  tcp::socket socket(io);
  socket.connect({asio::ip::make_address("127.0.0.1"), port});
  http::request<http::string_body> request{http::verb::post, "/api/login", 11};
  const std::string host = "127.0.0.1:" + std::to_string(port);
  request.set(http::field::host, host);
  request.set(http::field::origin, "http://" + host);
  request.set(http::field::content_type, "application/json");
  request.body() = json{{"token", kToken}}.dump();
  request.prepare_payload();
  http::write(socket, request);
  beast::flat_buffer buffer;
  http::response<http::string_body> reply;
  http::read(socket, buffer, reply);
  if (reply.result() != http::status::ok)
    throw std::runtime_error("the login was refused: " + reply.body());
  const std::string cookie(reply[http::field::set_cookie]);
  return cookie.substr(0, cookie.find(';'));
}

// A browser's WebSocket: logged in, subscribed, then every message read and timed.
class WsClient : public std::enable_shared_from_this<WsClient> {
 public:
  WsClient(asio::io_context& io, std::uint16_t port) : ws_(io) {
    const std::string cookie = logIn(io, port);
    const std::string host = "127.0.0.1:" + std::to_string(port);
    beast::get_lowest_layer(ws_).connect({asio::ip::make_address("127.0.0.1"), port});
    ws_.set_option(websocket::stream_base::decorator([cookie, host](websocket::request_type& r) {
      r.set(http::field::cookie, cookie);
      r.set(http::field::origin, "http://" + host);
    }));
    ws_.handshake(host, "/ws");
    ws_.text(true);
    ws_.write(asio::buffer(std::string(R"({"cmd":"subscribe","id":1})")));
    beast::flat_buffer answer;
    ws_.read(answer);  // the subscription's answer: events follow it
    if (!json::parse(beast::buffers_to_string(answer.data())).value("ok", false))
      throw std::runtime_error("subscribe was refused on the WebSocket");
  }
  void start() { read(); }
  void close() {
    beast::error_code ec;
    beast::get_lowest_layer(ws_).close(ec);
  }
  Arrivals arrivals;

 private:
  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return;
      self->arrivals.add(beast::buffers_to_string(self->buffer_.data()));
      self->buffer_.consume(self->buffer_.size());
      self->read();
    });
  }
  websocket::stream<tcp::socket> ws_;
  beast::flat_buffer buffer_;
};

// The TCP port's subscriber, the same events by the other transport.
class TcpSubscriber : public std::enable_shared_from_this<TcpSubscriber> {
 public:
  TcpSubscriber(asio::io_context& io, std::uint16_t port) : socket_(io) {
    socket_.connect({asio::ip::make_address("127.0.0.1"), port});
    asio::write(socket_, asio::buffer(json{{"cmd", "auth"}, {"id", 1}, {"token", kToken}}.dump() +
                                      "\n{\"cmd\":\"subscribe\",\"id\":2}\n"));
    for (int answers = 0; answers < 2;) {
      asio::read_until(socket_, input_, '\n');
      std::string line;
      std::istream in(&input_);
      std::getline(in, line);
      if (!json::parse(line).value("ok", false))
        throw std::runtime_error("the TCP subscriber was refused: " + line);
      ++answers;
    }
  }
  void start() { read(); }
  void close() {
    boost::system::error_code ec;
    socket_.close(ec);
  }
  Arrivals arrivals;

 private:
  void read() {
    asio::async_read_until(socket_, input_, '\n',
                           [self = shared_from_this()](boost::system::error_code ec, std::size_t) {
                             if (ec) return;
                             std::string line;
                             std::istream in(&self->input_);
                             std::getline(in, line);
                             self->arrivals.add(std::move(line));
                             self->read();
                           });
  }
  tcp::socket socket_;
  asio::streambuf input_;
};

int run(const std::string& zerocald, int clients, double pace, double max_p99_ms,
        double max_event_ms) {
  char pattern[] = "/tmp/zerocal-bench-web-XXXXXX";
  if (::mkdtemp(pattern) == nullptr) throw std::runtime_error("mkdtemp failed");
  const fs::path dir = pattern;
  int failed = 0;
  {
    Daemon daemon(zerocald, dir, pace);
    asio::io_context io;
    std::vector<std::shared_ptr<WsClient>> browsers;
    for (int i = 0; i < clients; ++i)
      browsers.push_back(std::make_shared<WsClient>(io, daemon.web_port));
    auto tcp_subscriber = std::make_shared<TcpSubscriber>(io, daemon.control_port);
    for (auto& b : browsers) b->start();
    tcp_subscriber->start();
    std::thread readers([&io] { io.run(); });

    zerocal::control::ControlClient poller;
    poller.connect("127.0.0.1", daemon.control_port);
    poller.authenticate(kToken);
    poller.call("start", {{"kind", "reference"}});
    const auto started = Clock::now();
    std::vector<double> round_trips;
    std::string state;
    for (;;) {
      const auto t0 = Clock::now();
      const json status = poller.call("status")["status"];
      round_trips.push_back(ms(Clock::now() - t0));
      state = status.value("state", "");
      // The session's end (idle only until the start has reached the worker).
      if (!status.value("active", true) && state != "idle") break;
      if (Clock::now() - started > 600s) throw std::runtime_error("the session did not end");
      std::this_thread::sleep_for(2ms);
    }
    const double session_s = std::chrono::duration<double>(Clock::now() - started).count();
    std::this_thread::sleep_for(500ms);  // the last events on their way
    asio::post(io, [&] {
      for (auto& b : browsers) b->close();
      tcp_subscriber->close();
    });
    readers.join();

    // Every subscriber got the same lines in the same order: the k-th is the same event.
    const Arrivals& reference = tcp_subscriber->arrivals;
    std::vector<double> delays;
    int lost = 0;
    for (std::size_t k = 0; k < reference.lines.size(); ++k) {
      Clock::time_point first = reference.times[k];
      for (auto& b : browsers)
        if (k < b->arrivals.times.size()) first = std::min(first, b->arrivals.times[k]);
      for (auto& b : browsers) {
        if (k >= b->arrivals.lines.size() || b->arrivals.lines[k] != reference.lines[k]) {
          ++lost;
          continue;
        }
        delays.push_back(ms(b->arrivals.times[k] - first));
      }
    }
    std::sort(round_trips.begin(), round_trips.end());
    std::sort(delays.begin(), delays.end());
    const double p99 = percentile(round_trips, 0.99);
    const double event_p99 = percentile(delays, 0.99);
    const double event_max = delays.empty() ? 0 : delays.back();
    std::printf("session: reference, %s after %.1f s (sim_pace %.2f), %d WebSocket clients\n",
                state.c_str(), session_s, pace, clients);
    std::printf(
        "status round trip on the TCP port: %zu calls, p50 %.3f ms, p99 %.3f ms, max %.3f "
        "ms (requirement p99 < %.1f ms)\n",
        round_trips.size(), percentile(round_trips, 0.5), p99, round_trips.back(), max_p99_ms);
    std::printf(
        "events: %zu to each of %d subscribers; delay at a WebSocket after the first "
        "arrival: p50 %.3f ms, p99 %.3f ms, max %.3f ms (requirement < %.0f ms); %d "
        "missing or out of order\n",
        reference.lines.size(), clients + 1, percentile(delays, 0.5), event_p99, event_max,
        max_event_ms, lost);
    if (state != "done") {
      std::printf("FAIL: the session ended %s\n", state.c_str());
      failed = 1;
    }
    if (p99 >= max_p99_ms) {
      std::printf("FAIL: status p99 %.3f ms >= %.1f ms\n", p99, max_p99_ms);
      failed = 1;
    }
    if (event_max >= max_event_ms || lost > 0 || reference.lines.empty()) {
      std::printf("FAIL: an event was late, lost or none came\n");
      failed = 1;
    }
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  return failed;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"load and latency of the web terminal on zerocald --sim"};
  std::string zerocald = "build/bin/zerocald";
  int clients = 20;
  double pace = 0.2, max_p99_ms = 5, max_event_ms = 100;
  app.add_option("--zerocald", zerocald, "the daemon to start")->default_val(zerocald);
  app.add_option("--clients", clients, "WebSocket clients following the session")
      ->default_val(clients)
      ->check(CLI::Range(0, 100));
  app.add_option("--pace", pace, "backend.sim_pace: wall seconds per cell second")
      ->default_val(pace)
      ->check(CLI::PositiveNumber);
  app.add_option("--max-p99-ms", max_p99_ms, "requirement on the status round trip's p99")
      ->default_val(max_p99_ms);
  app.add_option("--max-event-ms", max_event_ms, "requirement on an event's delay")
      ->default_val(max_event_ms);
  CLI11_PARSE(app, argc, argv);
  try {
    return run(zerocald, clients, pace, max_p99_ms, max_event_ms);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_web: %s\n", e.what());
    return 2;
  }
}
