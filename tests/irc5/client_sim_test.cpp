// Protocol tests: the real Irc5Client against the real simulated controller on an ephemeral
// loopback port. Moves run on the simulated clock, so nothing here waits for a robot.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <thread>

#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal {
namespace {

using std::chrono::milliseconds;

// A plain blocking socket with a receive timeout, for bytes the client would refuse to send.
class RawSocket {
 public:
  explicit RawSocket(std::uint16_t port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    timeval tv{2, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  ~RawSocket() { ::close(fd_); }
  bool connected() const { return connected_; }
  void send(const std::string& s) {
    ASSERT_EQ(::send(fd_, s.data(), s.size(), 0), ssize_t(s.size()));
  }
  // Reads up to LF (bounded by the 2 s receive timeout).
  std::string line() {
    std::string out;
    char c;
    while (::recv(fd_, &c, 1, 0) == 1) {
      if (c == '\n') return out;
      out += c;
    }
    return out + "<timeout>";
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

World testWorld() {
  World w = randomWorld(7, WorldKind::kIdeal);  // exact: the protocol is under test
  w.noise.repeatability_deg = 0;  // exact read-backs below; noise is tested separately
  return w;
}

class ClientSim : public ::testing::Test {
 protected:
  void startSim(bool lf = true, bool real_time = false) {
    SimControllerOptions o;
    o.world = testWorld();
    o.lf_terminated = lf;
    o.pace = real_time ? 1.0 : 0.0;
    o.partial_request_timeout = milliseconds(100);
    sim_ = std::make_unique<SimController>(o);
    sim_->start();
  }
  Irc5Options clientOptions(bool lf = true) {
    Irc5Options o;
    o.host = "127.0.0.1";
    o.port = sim_->port();
    o.robot = builtinIrb1600();
    o.lf_terminated = lf;
    o.request_timeout = milliseconds(1000);
    o.move_timeout_factor = 1.0;
    o.move_timeout_margin = milliseconds(1000);
    o.reconnect_attempts = 3;
    o.backoff_initial = milliseconds(10);
    return o;
  }
  std::unique_ptr<SimController> sim_;
};

TEST_F(ClientSim, ConnectRunsTheSetupSequence) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  EXPECT_TRUE(client.connected());
  EXPECT_EQ(client.info().serial, "SIM-1600-0001");
  EXPECT_EQ(client.info().software_version, "6.15.01.00");
  EXPECT_EQ(client.info().robot_type, "IRB 1600-10/1.45");
  EXPECT_EQ(sim_->requestCount(), 8);  // ping, 98, tool, wobj, speed, zone, 42 lower, 42 upper
}

TEST_F(ClientSim, ARobotFileWiderThanTheControllersBoundsIsRefusedAtConnect) {
  startSim();
  Irc5Options options = clientOptions();
  options.robot.limits[0] = {-360, 360};
  options.robot.limits[3].upper_deg += 1;
  const Joints home = sim_->commandedJoints();
  Irc5Client client(options);
  try {
    client.connect();
    FAIL() << "a robot file wider than the controller was accepted";
  } catch (const ConfigError& e) {
    ASSERT_EQ(e.problems().size(), 2u);
    EXPECT_NE(e.problems()[0].find("joint 1: the robot file allows -360.000..360.000 deg"),
              std::string::npos)
        << e.problems()[0];
    EXPECT_NE(e.problems()[1].find("joint 4"), std::string::npos) << e.problems()[1];
  }
  EXPECT_FALSE(client.connected());
  EXPECT_EQ(sim_->commandedJoints(), home);
  // A narrower file is the technician's choice and is kept.
  options = clientOptions();
  options.robot.limits[0] = {-90, 90};
  Irc5Client narrower(options);
  EXPECT_NO_THROW(narrower.connect());
}

TEST_F(ClientSim, PingAndReadJoints) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  client.ping();
  const Joints q = client.readJoints();
  for (int i = 0; i < kJointCount; ++i) EXPECT_EQ(q[i], sim_->commandedJoints()[i]);
  EXPECT_DOUBLE_EQ(q[4], 30.0);
}

TEST_F(ClientSim, FiveDecimalTargetReadsBackWithin1e5OfTheStoredFloat) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  const Joints target{12.34567, -23.45678, 34.56789, -123.45671, 45.67891, 234.56789};
  client.moveJoints(target);
  const Joints stored = sim_->commandedJoints();
  const Joints read = client.readJoints();
  for (int i = 0; i < kJointCount; ++i) {
    EXPECT_NEAR(read[i], stored[i], 1e-5) << "joint " << i + 1;
    EXPECT_EQ(stored[i], double(float(target[i])))  // the controller holds float32
        << std::setprecision(17) << stored[i] << " " << target[i] << " "
        << double(float(target[i]));
    EXPECT_NEAR(read[i], target[i], 2e-5);
  }
}

TEST_F(ClientSim, MoveAdvancesTheSimulatedClockNotTheWallClock) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  const auto t0 = std::chrono::steady_clock::now();
  // J6 alone: the flange origin stays put, the tool turns 100 deg at v_ori = 50 deg/s: 2 s of
  // cruise, 50 / 1000 s more for the ramps, plus the fixed cost and the fine-point settling.
  client.moveJoints({0, 0, 0, 0, 30, 100});
  const irc5::MotionCosts costs;
  EXPECT_NEAR(sim_->simTimeS(), 2.0 + 50.0 / costs.joint_accel_deg_s2 + 0.3 + 0.1, 1e-5);
  const MotionTotals first = sim_->motionTotals();
  EXPECT_EQ(first.moves, 1);
  EXPECT_NEAR(first.motion_s, 2.05, 1e-5);
  EXPECT_NEAR(first.overhead_s, 0.3, 1e-12);
  EXPECT_NEAR(first.settle_s, 0.1, 1e-12);
  // J1 swings the flange along an arc of about 100 deg x 0.85 m: v_tcp = 100 mm/s limits.
  client.moveJoints({100, 0, 0, 0, 30, 100});
  EXPECT_GT(sim_->simTimeS() - 2.45, 12.0 + 0.4);
  EXPECT_EQ(sim_->motionTotals().moves, 2);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, milliseconds(500));
}

TEST_F(ClientSim, EveryMovePaysTheFixedCostEvenWhenTiny) {
  SimControllerOptions o;
  o.world = testWorld();
  o.motion.overhead_s = 1.0;
  o.motion.settle_s = 0.0;
  sim_ = std::make_unique<SimController>(o);
  sim_->start();
  Irc5Client client(clientOptions());
  client.connect();
  // 1e-3 deg of J6: the triangular profile takes 2 sqrt(1e-3 / 1000) = 2 ms.
  client.moveJoints({0, 0, 0, 0, 30, 0.001});
  EXPECT_NEAR(sim_->simTimeS(), 1.0 + 2 * std::sqrt(1e-3 / 1000.0), 1e-4);
  o.motion.joint_accel_deg_s2 = 0;
  EXPECT_THROW({ SimController bad(o); }, ConfigError);
}

TEST_F(ClientSim, RealTimePacedMoveUsesTheMoveDeadlineNotTheRequestTimeout) {
  startSim(true, /*real_time=*/true);
  Irc5Options o = clientOptions();
  o.request_timeout = milliseconds(100);
  o.move_timeout_factor = 2.0;
  o.move_timeout_margin = milliseconds(800);
  Irc5Client client(o);
  client.connect();
  const auto t0 = std::chrono::steady_clock::now();
  // J6 only: 10 deg at 50 deg/s, 0.2 s, and 0.45 s of ramps, fixed cost and settling; the
  // deadline: 0.2 s x 2 + the margin.
  client.moveJoints({0, 0, 0, 0, 30, 10});
  EXPECT_GE(std::chrono::steady_clock::now() - t0, milliseconds(640));
}

TEST_F(ClientSim, ReadPoseIsTheForwardKinematicsOfTheReportedJoints) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  client.moveJoints({10, 20, -10, 30, 40, 50});
  const TcpPose p = client.readPose();
  const Frame<double> f = flangePoseDeg(builtinIrb1600(), client.readJoints());
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(p.xyz_mm[i], f.p[i], 2e-3);
  const Eigen::Quaterniond q(p.quat_wxyz[0], p.quat_wxyz[1], p.quat_wxyz[2], p.quat_wxyz[3]);
  EXPECT_LT(Eigen::AngleAxisd(q.toRotationMatrix().transpose() * f.R).angle(), 1e-5);
}

TEST_F(ClientSim, MoveLinearReachesTheTargetPose) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  client.moveJoints({0, 10, 10, 0, 40, 0});
  TcpPose target = client.readPose();
  target.xyz_mm[0] += 10;
  target.xyz_mm[1] -= 5;
  target.xyz_mm[2] += 20;
  client.moveLinear(target);
  const TcpPose p = client.readPose();
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(p.xyz_mm[i], target.xyz_mm[i], 2e-3);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(p.quat_wxyz[i], target.quat_wxyz[i], 2e-6);
}

TEST_F(ClientSim, UnreachableLinearTargetIsABadMessage) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  EXPECT_THROW(client.moveLinear({{5000, 0, 0}, {1, 0, 0, 0}}), BadMessageError);
  EXPECT_NO_THROW(client.ping());
}

TEST_F(ClientSim, Extensions) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  EXPECT_NO_THROW(client.stop());
  for (double v : client.readExternalAxes()) EXPECT_EQ(v, 9e9);
  for (double v : client.readCalOffsets()) EXPECT_LE(std::abs(v), 2 * kPi);
  const auto bounds = client.readJointBounds();
  const Robot robot = builtinIrb1600();
  for (int i = 0; i < kJointCount; ++i) {
    EXPECT_EQ(bounds[i].lower_deg, robot.limits[i].lower_deg);
    EXPECT_EQ(bounds[i].upper_deg, robot.limits[i].upper_deg);
  }
}

TEST_F(ClientSim, UnsupportedAndUnknownCodesAreBadMessagesAndTheLinkSurvives) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  for (int code = 30; code <= 36; ++code) {
    try {
      client.rawRequest((code < 10 ? "0" : "") + std::to_string(code) + " #", 0, milliseconds(500));
      ADD_FAILURE() << code;
    } catch (const BadMessageError& e) {
      EXPECT_EQ(e.code(), code);
      EXPECT_NE(std::string(e.what()).find("not supported"), std::string::npos);
    }
  }
  EXPECT_THROW(client.rawRequest("77 #", 0, milliseconds(500)), BadMessageError);
  EXPECT_THROW(client.rawRequest("02 1 2 3 #", 0, milliseconds(500)), BadMessageError);
  EXPECT_TRUE(client.connected());
  EXPECT_NO_THROW(client.readJoints());
}

TEST_F(ClientSim, EveryCommandWithoutLf) {
  startSim(/*lf=*/false);
  Irc5Client client(clientOptions(/*lf=*/false));
  client.connect();
  EXPECT_EQ(client.info().robot_type, "IRB 1600-10/1.45");
  client.ping();
  client.moveJoints({1.23456, 2, 3, 4, 5, 6});
  EXPECT_NEAR(client.readJoints()[0], 1.23456, 1e-5);
  TcpPose p = client.readPose();
  p.xyz_mm[2] += 5;
  client.moveLinear(p);
  EXPECT_NEAR(client.readPose().xyz_mm[2], p.xyz_mm[2], 2e-3);
  EXPECT_EQ(client.readJointBounds()[5].upper_deg, 400);
  EXPECT_THROW(client.rawRequest("31 #", 0, milliseconds(500)), BadMessageError);
  EXPECT_NO_THROW(client.ping());  // the refusal's text was consumed, the stream is in step
}

TEST_F(ClientSim, SplitRepliesWithAndWithoutLf) {
  for (bool lf : {true, false}) {
    startSim(lf);
    SimFaults f;
    f.split_replies = true;
    f.split_gap = milliseconds(5);
    sim_->setFaults(f);
    Irc5Client client(clientOptions(lf));
    client.connect();
    EXPECT_EQ(client.info().robot_type, "IRB 1600-10/1.45") << lf;
    client.moveJoints({-12.5, 3, 4, 5, 6, 7});
    EXPECT_EQ(client.readJoints()[0], -12.5) << lf;
    EXPECT_NO_THROW(client.readPose()) << lf;
  }
}

TEST_F(ClientSim, OverlongAndMalformedRequestsAreRefusedBeforeSending) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  const long before = sim_->requestCount();
  EXPECT_THROW(client.rawRequest("02 " + std::string(77, '1') + " #", 0, milliseconds(500)),
               RequestRefusedError);
  EXPECT_THROW(client.rawRequest("04 ", 6, milliseconds(500)), RequestRefusedError);
  EXPECT_THROW(client.rawRequest("04 #\n", 6, milliseconds(500)), RequestRefusedError);
  EXPECT_EQ(sim_->requestCount(), before);
  EXPECT_NO_THROW(client.readJoints());
}

TEST_F(ClientSim, ServerAnswersARequestMissingItsHashWithItsOwnCode) {
  startSim();
  RawSocket raw(sim_->port());
  ASSERT_TRUE(raw.connected());
  raw.send("04 ");
  EXPECT_EQ(raw.line(), "4 0 request without '#'");
  raw.send("04 #");
  EXPECT_EQ(raw.line(), "4 1 0.00000 0.00000 0.00000 0.00000 30.00000 0.00000");
}

// What open_abb's abb.py does with a reply: split on ' ' and float() every token (Python's float
// accepts surrounding whitespace, so our LF on the last token is fine, a trailing " \n" is not).
bool pythonFloatsAll(const std::string& reply) {
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = std::min(reply.find(' ', start), reply.size());
    std::string token = reply.substr(start, end - start);
    while (!token.empty() && std::isspace(static_cast<unsigned char>(token.back())))
      token.pop_back();
    char* stop = nullptr;
    std::strtod(token.c_str(), &stop);
    if (token.empty() || *stop != '\0') return false;
    if (end == reply.size()) return true;
    start = end + 1;
  }
}

TEST_F(ClientSim, ServerAcceptsTheUpstreamPythonClientsBytes) {
  startSim();
  RawSocket raw(sim_->port());
  ASSERT_TRUE(raw.connected());
  // Byte for byte what abb.py's Robot() sends: format(x, "+08.1f") etc.
  raw.send("06 +00000.0 +00000.0 +00000.0 +1.00000 +0.00000 +0.00000 +0.00000 #");
  EXPECT_EQ(raw.line(), "6 1 ");
  raw.send("07 +00000.0 +00000.0 +00000.0 +1.00000 +0.00000 +0.00000 +0.00000 #");
  EXPECT_EQ(raw.line(), "7 1 ");
  raw.send("08 +00100.0 +0050.00 +00050.0 +0050.00 #");
  EXPECT_EQ(raw.line(), "8 1 ");
  raw.send("09 0 +01.0000 +01.0000 +00.1000 #");  // setZone('z1')
  EXPECT_EQ(raw.line(), "9 1 ");
  raw.send("02 +0010.00 -0005.25 +0000.00 +0000.00 +0090.00 +0000.00 #");
  EXPECT_EQ(raw.line(), "2 1 ");
  raw.send("04 #");
  const std::string joints = raw.line();
  EXPECT_EQ(joints, "4 1 10.00000 -5.25000 0.00000 0.00000 90.00000 0.00000");
  EXPECT_TRUE(pythonFloatsAll(joints + "\n"));
  raw.send("01 +00900.0 +00000.0 +00900.0 +0.70711 +0.00000 +0.70711 +0.00000 #");
  EXPECT_EQ(raw.line(), "1 1 ");
  raw.send("03 #");
  const std::string pose = raw.line();
  EXPECT_EQ(pose.substr(0, 24), "3 1 900.000 0.000 900.00");
  EXPECT_TRUE(pythonFloatsAll(pose + "\n"));
  raw.send("05 #");
  EXPECT_TRUE(pythonFloatsAll(raw.line() + "\n"));
  raw.send("98 #");
  EXPECT_EQ(raw.line().substr(5), "SIM-1600-0001*6.15.01.00*IRB 1600-10/1.45");  // abb.py: [5:]
  // A request split across segments, and a stray LF after '#', stay in step.
  raw.send("0");
  raw.send("0 #\n");
  EXPECT_EQ(raw.line(), "0 1 ");
  raw.send("00 #");
  EXPECT_EQ(raw.line(), "0 1 ");
}

TEST_F(ClientSim, EveryReplyFitsEightyCharactersWithItsLf) {
  startSim();
  RawSocket raw(sim_->port());
  ASSERT_TRUE(raw.connected());
  raw.send("02 -179.99999 -89.99999 -244.99999 -199.99999 -114.99999 -399.99999 #");
  EXPECT_EQ(raw.line(), "2 1 ");
  for (const char* request :
       {"00 #", "03 #", "04 #", "05 #", "41 #", "42 0 #", "42 1 #", "98 #", "30 #", "77 #"}) {
    raw.send(request);
    const std::string line = raw.line();
    EXPECT_LE(line.size() + 1, 80u) << request << " -> " << line;
    EXPECT_EQ(line.find("<timeout>"), std::string::npos) << request;
  }
}

TEST_F(ClientSim, LimitsAreRefusedOnBothSides) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  const long before = sim_->requestCount();
  EXPECT_THROW(client.moveJoints({0, 0, 70, 0, 30, 0}), RequestRefusedError);  // J3 <= 65
  EXPECT_EQ(sim_->requestCount(), before);

  // A robot file wider than the controller's bounds is refused at connect; nothing moves.
  Irc5Options wide = clientOptions();
  wide.robot.limits[4] = {-150, 150};
  Irc5Client loose(wide);
  EXPECT_THROW(loose.connect(), ConfigError);
  EXPECT_EQ(sim_->commandedJoints()[4], 30.0);
}

TEST_F(ClientSim, LimitMarginAndStepLimitRefuseBeforeSending) {
  startSim();
  Irc5Options o = clientOptions();
  o.limit_margin_deg = 1.0;
  o.max_step_deg = 5.0;
  Irc5Client client(o);
  client.connect();
  EXPECT_NO_THROW(client.moveJoints({4.9, 0, 0, 0, 30, 0}));
  EXPECT_THROW(client.moveJoints({10, 0, 0, 0, 30, 0}), RequestRefusedError);
  EXPECT_THROW(client.moveJoints({4.9, 0, 64.5, 0, 30, 0}), RequestRefusedError);  // margin
  EXPECT_EQ(sim_->commandedJoints()[0], double(float(4.9)));
}

TEST_F(ClientSim, DroppedConnectionThenReconnect) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  SimFaults f;
  f.drop_after_requests = 10;  // the 8 setup requests and two reads
  sim_->setFaults(f);
  EXPECT_NO_THROW(client.readJoints());
  EXPECT_NO_THROW(client.readJoints());
  EXPECT_THROW(client.readJoints(), ConnectionError);
  EXPECT_FALSE(client.connected());
  EXPECT_THROW(client.ping(), ConnectionError);  // no silent reconnect
  client.reconnect();
  EXPECT_NO_THROW(client.readJoints());
  EXPECT_EQ(sim_->connectionCount(), 2);
}

TEST_F(ClientSim, DelayedReplyTimesOutAndClosesTheLink) {
  startSim();
  Irc5Options o = clientOptions();
  o.request_timeout = milliseconds(100);
  Irc5Client client(o);
  client.connect();
  SimFaults f;
  f.reply_delay = milliseconds(300);
  sim_->setFaults(f);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(client.readJoints(), TimeoutError);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, milliseconds(280));
  EXPECT_FALSE(client.connected());  // a late reply must not answer the next request
  sim_->setFaults({});
  client.reconnect();
  EXPECT_NO_THROW(client.readJoints());
}

TEST_F(ClientSim, DelayWithinTheDeadlineIsFine) {
  startSim();
  Irc5Client client(clientOptions());
  SimFaults f;
  f.reply_delay = milliseconds(20);
  sim_->setFaults(f);
  client.connect();
  EXPECT_NO_THROW(client.readJoints());
}

TEST_F(ClientSim, GarbageReplyIsAProtocolErrorWithAndWithoutLf) {
  for (bool lf : {true, false}) {
    startSim(lf);
    Irc5Client client(clientOptions(lf));
    client.connect();
    SimFaults f;
    f.garbage_code = 4;
    sim_->setFaults(f);
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_THROW(client.readJoints(), ProtocolError) << lf;
    EXPECT_LT(std::chrono::steady_clock::now() - t0, milliseconds(500)) << lf;  // no timeout
    EXPECT_FALSE(client.connected());
    sim_->setFaults({});
    EXPECT_NO_THROW(client.reconnect());
    EXPECT_NO_THROW(client.ping());
  }
}

TEST_F(ClientSim, StalledMoveTimesOutAfterTheMoveDeadline) {
  startSim();
  Irc5Options o = clientOptions();
  o.move_timeout_margin = milliseconds(200);
  Irc5Client client(o);
  client.connect();
  SimFaults f;
  f.stall_moves = true;
  sim_->setFaults(f);
  client.readJoints();
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(client.moveJoints({0, 0, 0, 0, 30, 1}), TimeoutError);  // 20 ms + 200 ms
  const auto elapsed = std::chrono::steady_clock::now() - t0;
  EXPECT_GE(elapsed, milliseconds(200));
  EXPECT_LT(elapsed, milliseconds(1000));
  sim_->setFaults({});
  client.reconnect();
  EXPECT_NO_THROW(client.ping());
}

TEST_F(ClientSim, WrongReplyCodeIsAProtocolError) {
  // A one-shot server answering every request as if it were a joints read.
  startSim();
  const std::uint16_t port = sim_->port();
  sim_.reset();  // frees the port for the fake below
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  int one = 1;
  ::setsockopt(listener, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ::listen(listener, 1);
  std::thread fake([listener] {
    const int fd = ::accept(listener, nullptr, nullptr);
    char buf[128];
    if (::recv(fd, buf, sizeof buf, 0) > 0) {
      const std::string reply = "4 1 0 0 0 0 0 0\n";
      ::send(fd, reply.data(), reply.size(), 0);
    }
    ::recv(fd, buf, sizeof buf, 0);  // until the client closes
    ::close(fd);
  });
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = port;
  o.robot = builtinIrb1600();
  Irc5Client client(o);
  EXPECT_THROW(client.connect(), ProtocolError);  // the ping got a code-4 reply
  EXPECT_FALSE(client.connected());
  client.close();
  fake.join();
  ::close(listener);
}

TEST_F(ClientSim, ConnectionRefusedAndReconnectGivesUp) {
  startSim();
  const std::uint16_t port = sim_->port();
  sim_.reset();
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = port;
  o.robot = builtinIrb1600();
  o.reconnect_attempts = 3;
  o.backoff_initial = milliseconds(10);
  Irc5Client client(o);
  EXPECT_THROW(client.connect(), ConnectionError);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(client.reconnect(), ConnectionError);
  EXPECT_GE(std::chrono::steady_clock::now() - t0, milliseconds(30));  // 10 + 20 ms back-off
}

TEST_F(ClientSim, CloseSends99AndTheServerListensAgain) {
  startSim();
  Irc5Client client(clientOptions());
  client.connect();
  client.close();
  EXPECT_FALSE(client.connected());
  client.connect();
  EXPECT_NO_THROW(client.readJoints());
  EXPECT_EQ(sim_->connectionCount(), 2);
}

TEST_F(ClientSim, RepeatabilityNoiseMovesTheTruePoseNotTheReportedJoints) {
  SimControllerOptions so;
  so.world = testWorld();
  so.world.noise.repeatability_deg = 1e-3;
  sim_ = std::make_unique<SimController>(so);
  sim_->start();
  Irc5Client client(clientOptions());
  client.connect();
  client.moveJoints({0, 10, 10, 0, 40, 0});
  const Joints err = sim_->moveErrorDeg();
  double sum = 0;
  for (double e : err) sum += std::abs(e);
  EXPECT_GT(sum, 0);
  EXPECT_LT(sum, 6 * 5e-3);
  EXPECT_EQ(client.readJoints()[1], 10.0);
  const auto hit = sim_->beamHitNow();
  const auto ideal = beamHit(sim_->world(), sim_->commandedJoints());
  ASSERT_TRUE(hit && ideal);
  EXPECT_NE(hit->spot.u_mm, ideal->spot.u_mm);
  EXPECT_NEAR(hit->spot.u_mm, ideal->spot.u_mm, 1.0);
}

TEST(Irc5Options, InconsistentOptionsAreAConfigError) {
  Irc5Options o;  // no robot: no limits
  EXPECT_THROW(Irc5Client{o}, ConfigError);
  o.robot = builtinIrb1600();
  o.speed_ori_deg_s = 0;
  EXPECT_THROW(Irc5Client{o}, ConfigError);
}

}  // namespace
}  // namespace zerocal
