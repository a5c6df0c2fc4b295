#include "line_kind.h"

#include <algorithm>
#include <boost/asio.hpp>
#include <cmath>
#include <sstream>
#include <vector>

#include "zerocal/cell/link_error.h"

namespace zerocal::testing {
namespace {

namespace asio = boost::asio;
using asio::ip::tcp;

std::vector<std::string> wordsOf(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

template <std::size_t N>
bool numbersOf(const std::vector<std::string>& words, std::size_t first,
               std::array<double, N>& out) {
  if (words.size() != first + N) return false;
  for (std::size_t i = 0; i < N; ++i) {
    char* end = nullptr;
    out[i] = std::strtod(words[first + i].c_str(), &end);
    if (end != words[first + i].c_str() + words[first + i].size() || !std::isfinite(out[i]))
      return false;
  }
  return true;
}

template <class Container>
std::string joined(const Container& values) {
  std::ostringstream out;
  out.precision(17);
  for (double v : values) out << ' ' << v;
  return out.str();
}

std::string refusalOf(const sim::MoveResult& r) {
  switch (r.refusal) {
    case sim::MoveRefusal::kNone:
      return "OK";
    case sim::MoveRefusal::kUnreachable:
      return "ERR unreachable";
    default:
      return "ERR out_of_limits";
  }
}

// The fake's whole protocol: a line in, a line out.
std::string answer(sim::SimulatedArm& arm, const std::string& line) {
  const std::vector<std::string> w = wordsOf(line);
  if (w.empty()) return "ERR empty";
  const std::string& verb = w[0];
  if (verb == "PING" && w.size() == 1) return "OK";
  if (verb == "HELLO" && w.size() == 1) {
    const RobotInfo& id = arm.identity();
    return "OK " + id.robot_type + " " + id.serial + " " + id.software_version;
  }
  if (verb == "JOINTS" && w.size() == 1) return "OK" + joined(arm.joints());
  if (verb == "POSE" && w.size() == 1) {
    const TcpPose p = arm.toolPose();
    return "OK" + joined(p.xyz_mm) + joined(p.quat_wxyz);
  }
  std::array<double, 2> speed{};
  if (verb == "SPEED" && numbersOf(w, 1, speed)) {
    if (!(speed[0] > 0 && speed[1] > 0)) return "ERR bad_speed";
    arm.setSpeed({speed[0], speed[1]});
    return "OK";
  }
  Joints q{};
  if (verb == "MOVEJ" && numbersOf(w, 1, q)) return refusalOf(arm.moveJoints(q));
  std::array<double, 7> pose{};
  if (verb == "MOVEL" && numbersOf(w, 1, pose)) {
    TcpPose target;
    std::copy(pose.begin(), pose.begin() + 3, target.xyz_mm.begin());
    std::copy(pose.begin() + 3, pose.end(), target.quat_wxyz.begin());
    return refusalOf(arm.moveLinear(target));
  }
  return "ERR unknown_request";
}

// The line link: one blocking socket, one request at a time (the session's worker is the only
// thread that uses a link).
class LineClient final : public ControllerConnection {
 public:
  LineClient(Robot robot, std::string host, std::uint16_t port, double speed_tcp_mm_s,
             double limit_margin_deg)
      : robot_(std::move(robot)),
        host_(std::move(host)),
        port_(port),
        speed_tcp_mm_s_(speed_tcp_mm_s),
        margin_deg_(limit_margin_deg) {}

  void connect() override {
    close();
    boost::system::error_code ec;
    tcp::resolver resolver(io_);
    const auto endpoints = resolver.resolve(host_, std::to_string(port_), ec);
    if (!ec) asio::connect(socket_, endpoints, ec);
    if (ec)
      throw LinkError(LinkError::Kind::kTransient, "line controller at " + host_ + ":" +
                                                       std::to_string(port_) + ": " + ec.message());
    const auto hello = request("HELLO");
    if (hello.size() != 4) throw LinkError(LinkError::Kind::kFatal, "not a line controller");
    info_ = {hello[2], hello[3], hello[1]};
    request("SPEED " + std::to_string(speed_tcp_mm_s_) + " 100");
  }
  void reconnect() override { connect(); }
  void stop() override {}  // every move ends at its target before the reply
  bool connected() const noexcept override { return socket_.is_open(); }
  void close() noexcept override {
    boost::system::error_code ec;
    socket_.close(ec);
  }

  void ping() override { request("PING"); }
  RobotInfo robotInfo() override { return info_; }
  Joints readJoints() override {
    const auto reply = request("JOINTS");
    Joints q{};
    if (!numbersOf(reply, 1, q)) throw LinkError(LinkError::Kind::kTransient, "bad JOINTS reply");
    return q;
  }
  TcpPose readPose() override {
    const auto reply = request("POSE");
    std::array<double, 7> v{};
    if (!numbersOf(reply, 1, v)) throw LinkError(LinkError::Kind::kTransient, "bad POSE reply");
    TcpPose p;
    std::copy(v.begin(), v.begin() + 3, p.xyz_mm.begin());
    std::copy(v.begin() + 3, v.end(), p.quat_wxyz.begin());
    return p;
  }
  void moveJoints(const Joints& target) override {
    // Checked here as well as by the controller: nothing beyond the margin is ever sent.
    if (!robot_.withinLimits(target, margin_deg_))
      throw LinkError(LinkError::Kind::kRefused, robot_.limitViolation(target, margin_deg_));
    request("MOVEJ" + joined(target));
  }
  void moveLinear(const TcpPose& target) override {
    request("MOVEL" + joined(target.xyz_mm) + joined(target.quat_wxyz));
  }

 private:
  std::vector<std::string> request(const std::string& line) {
    if (!socket_.is_open()) throw LinkError(LinkError::Kind::kTransient, "not connected");
    boost::system::error_code ec;
    asio::write(socket_, asio::buffer(line + "\n"), ec);
    std::size_t n = 0;
    if (!ec) n = asio::read_until(socket_, asio::dynamic_buffer(buffer_), '\n', ec);
    if (ec) {
      close();
      throw LinkError(LinkError::Kind::kTransient, "line controller: " + ec.message());
    }
    const std::string reply = buffer_.substr(0, n - 1);
    buffer_.erase(0, n);
    auto words = wordsOf(reply);
    if (words.empty() || words[0] != "OK")
      throw LinkError(LinkError::Kind::kRefused,
                      "line controller refused '" + line + "': " + reply);
    return words;
  }

  Robot robot_;
  std::string host_;
  std::uint16_t port_;
  double speed_tcp_mm_s_, margin_deg_;
  asio::io_context io_;
  tcp::socket socket_{io_};
  std::string buffer_;
  RobotInfo info_;
};

}  // namespace

double LineMotion::motionS(const Joints& from, const Joints& to) const {
  double largest = 0;
  for (std::size_t i = 0; i < from.size(); ++i)
    largest = std::max(largest, std::abs(to[i] - from[i]));
  return largest / joint_speed_deg_s;
}

sim::MotionModel LineMotion::model() const {
  sim::MotionModel m;
  m.cruise_s = [*this](const Robot&, const Joints& from, const Joints& to, const sim::MoveSpeed&) {
    return motionS(from, to);
  };
  m.profile_s = [](double cruise_s, double) { return cruise_s; };
  m.overhead_s = overhead_s;
  m.settle_s = settle_s;
  return m;
}

struct LineServer::Impl {
  explicit Impl(sim::SimulatedArm& a) : arm(a) {}
  sim::SimulatedArm& arm;
  asio::io_context io;
  tcp::acceptor acceptor{io, tcp::endpoint(asio::ip::make_address("127.0.0.1"), 0)};

  void accept(std::atomic<long>& requests) {
    acceptor.async_accept([this, &requests](boost::system::error_code ec, tcp::socket socket) {
      if (ec) return;
      serve(std::make_shared<tcp::socket>(std::move(socket)), std::make_shared<std::string>(),
            requests);
      accept(requests);
    });
  }
  void serve(std::shared_ptr<tcp::socket> socket, std::shared_ptr<std::string> buffer,
             std::atomic<long>& requests) {
    asio::async_read_until(
        *socket, asio::dynamic_buffer(*buffer), '\n',
        [this, socket, buffer, &requests](boost::system::error_code ec, std::size_t n) {
          if (ec) return;
          const std::string line = buffer->substr(0, n - 1);
          buffer->erase(0, n);
          ++requests;
          auto reply = std::make_shared<std::string>(answer(arm, line) + "\n");
          asio::async_write(
              *socket, asio::buffer(*reply),
              [this, socket, buffer, reply, &requests](boost::system::error_code e, std::size_t) {
                if (!e) serve(socket, buffer, requests);
              });
        });
  }
};

LineServer::LineServer(sim::SimulatedArm& arm) : impl_(std::make_unique<Impl>(arm)) {
  port_ = impl_->acceptor.local_endpoint().port();
  impl_->accept(requests_);
  thread_ = std::thread([this] { impl_->io.run(); });
}

LineServer::~LineServer() {
  impl_->io.stop();
  thread_.join();
}

void LineSettings::declare(const std::string& prefix, settings::Fields& fields) {
  fields.push_back(settings::textField(prefix + "host", host));
  fields.push_back(settings::integerField(prefix + "port", port));
  fields.push_back(settings::realField(prefix + "speed_tcp_mm_s", speed_tcp_mm_s));
  fields.push_back(settings::realField(prefix + "limit_margin_deg", limit_margin_deg));
}

void LineSettings::check(const std::string& prefix, bool, settings::Checker& check) const {
  if (host.empty()) check.fail(prefix + "host", "must not be empty");
  if (port == 0) check.fail(prefix + "port", "must be 1..65535");
  check.positive(prefix + "speed_tcp_mm_s", speed_tcp_mm_s, 1000.0);
  check.range(prefix + "limit_margin_deg", limit_margin_deg, 0.0, 10.0);
}

ControllerMotion LineSettings::motion() const {
  ControllerMotion m;
  m.travel_s = [model = motion_model](const Robot&, const Joints& from, const Joints& to) {
    return model.motionS(from, to);
  };
  m.settle_s = motion_model.settle_s;
  m.limit_margin_deg = limit_margin_deg;
  m.linear_speed_mm_s = speed_tcp_mm_s;
  m.restart_timeout = std::chrono::milliseconds(1000);
  return m;
}

std::unique_ptr<ControllerConnection> LineSettings::link(const Robot& robot,
                                                         const LinkEndpoint* endpoint) const {
  return std::make_unique<LineClient>(robot, endpoint ? endpoint->host : host,
                                      endpoint ? endpoint->port : port, speed_tcp_mm_s,
                                      limit_margin_deg);
}

ControllerKind lineKind() {
  return {"line", "a test controller speaking one text line a request",
          [] { return std::make_unique<LineSettings>(); }};
}

}  // namespace zerocal::testing
