// The blocking TCP client for zerocal's RAPID server (and upstream open_abb servers) on an IRC5.
// One request at a time, each in one write, each with a deadline; Boost.Asio stays inside the
// .cpp. Not thread-safe: one owner thread calls it. Once connected, the requests a servo cycle
// makes (moveJoints, readJoints, readPose, ping, ...) allocate nothing unless they throw.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "zerocal/cell/controller_link.h"
#include "zerocal/irc5/errors.h"
#include "zerocal/irc5/protocol.h"
#include "zerocal/model/robot.h"
#include "zerocal/psd/spot.h"

namespace zerocal {

struct Irc5Options {
  std::string host = "192.168.125.1";  // the IRC5 service port's address
  std::uint16_t port = 5000;
  // The robot file: its joint limits and speeds bound every move and its deadline.
  Robot robot;
  // Refuse joint targets closer than this to a limit (deg).
  double limit_margin_deg = 0.0;
  // Refuse joint moves whose largest joint step exceeds this (deg); 0 = no step limit.
  double max_step_deg = 0.0;

  std::chrono::milliseconds connect_timeout{2000};
  // Deadline of every request that does not move the robot.
  std::chrono::milliseconds request_timeout{1000};
  // A move's deadline: estimated duration * move_timeout_factor + move_timeout_margin.
  double move_timeout_factor = 2.0;
  std::chrono::milliseconds move_timeout_margin{2000};

  // Sent on connect (code 08): TCP mm/s, orientation deg/s, external axes mm/s and deg/s.
  // Move deadlines follow from these too (zerocal/irc5/motion_time.h).
  double speed_tcp_mm_s = 100.0;
  double speed_ori_deg_s = 50.0;
  double speed_leax_mm_s = 0.0;
  double speed_reax_deg_s = 0.0;

  // false: the server ends replies with no LF (upstream open_abb); replies are then read until the
  // expected fields have arrived, and a possibly unfinished last field is given reply_settle to
  // grow before it is accepted.
  bool lf_terminated = true;
  std::chrono::milliseconds reply_settle{30};

  // reconnect(): attempts, and the back-off between them (doubling up to the maximum).
  int reconnect_attempts = 5;
  std::chrono::milliseconds backoff_initial{100};
  std::chrono::milliseconds backoff_max{2000};
  // restartController(): how long the restarting controller may take to serve again, tried
  // with the same back-off. A warm start takes tens of seconds (docs/irc5.md).
  std::chrono::milliseconds restart_timeout{90000};
};

// What zerocal-sim says it simulates (simulator-only request 44).
struct SimWorldId {
  std::string hash;        // worldHash() of its world, 16 hex digits
  std::uint64_t seed = 0;  // its --seed (the world's, unless it was given --world)
};

class Irc5Client final : public ControllerConnection, public ControllerCalibration {
 public:
  // Does not connect. Throws ConfigError when the options are inconsistent.
  explicit Irc5Client(Irc5Options options);
  ~Irc5Client() override;
  Irc5Client(const Irc5Client&) = delete;
  Irc5Client& operator=(const Irc5Client&) = delete;

  // Connects within connect_timeout and runs the setup sequence: ping, robot info, tool0, wobj0,
  // speed, zone fine (09 1 0 0 0), the joint bounds (42). Throws ConnectionError, TimeoutError,
  // ProtocolError, BadMessageError; ConfigError when the robot file's joint limits are wider than
  // the controller's bounds (a server without request 42 cannot be used). On any failure the
  // connection is closed.
  void connect() override;
  // Closes and connects again, up to reconnect_attempts times with exponential back-off. Throws
  // the last attempt's LinkError when all fail.
  void reconnect() override;
  // Sends 99 (the server closes and listens again) when connected, then closes. Never throws.
  void close() noexcept override;
  bool connected() const noexcept override;
  // Robot info from the last connect() (empty before).
  const RobotInfo& info() const noexcept { return info_; }

  void ping() override;
  RobotInfo robotInfo() override;
  Joints readJoints() override;
  // Throws RequestRefusedError, before sending, for a target outside limits (less the margin) or
  // a step over max_step_deg; BadMessageError when the controller refuses it.
  void moveJoints(const Joints& target_deg) override;
  TcpPose readPose() override;
  // The quaternion is normalised before sending; throws RequestRefusedError for a zero one.
  void moveLinear(const TcpPose& target) override;

  // The continuous spot search (requests 47 and 49; docs/irc5.md). startSpotSearch() is false
  // when the server refuses the spiral's first row (upstream's, or a module whose light signal is
  // not configured). searchRun checks every waypoint against the limits less the margin and
  // every step against max_step_deg before sending (RequestRefusedError).
  bool startSpotSearch(const SpotSearch& search) override;
  std::optional<Joints> searchRun(const SearchRun& run) override;

  // Extensions (zerocal's server and simulator only; upstream replies ok = 0).
  void stop() override;
  std::array<double, 6> readExternalAxes();
  // MOC cal_offset of the six motors, radians, read only.
  std::array<double, 6> readCalOffsets() override;
  // Writes MOC MOTOR_CALIB cal_offset of joint (1..6), rad in [0, 2 pi), 6 decimals (request
  // 45, RAPID WriteCfgData). The motion system takes it at the controller's next restart; read
  // back with readCalOffsets. Throws BadMessageError when the controller refuses it.
  void writeCalOffset(int joint, double rad) override;
  // The six motors' angles now (request 48, RAPID ReadMotor), radians. Throws BadMessageError
  // from a server without request 48.
  std::array<double, 6> readMotorAngles() override;
  // Restarts the controller so that written system parameters take effect (request 46, RAPID
  // WarmStart), then connects again as soon as it serves, trying until restart_timeout. Throws
  // TimeoutError when it does not come back within it (the last attempt's error in the
  // message), a refused LinkError or ConfigError at once, as connect().
  void restartController();
  // ControllerCalibration: restartController().
  void restart() override { restartController(); }
  ControllerCalibration* calibration() noexcept override { return this; }
  // The controller's own joint bounds, degrees.
  std::array<JointLimit, kJointCount> readJointBounds();
  // Simulator only (zerocal-sim; the RAPID module replies ok = 0, thrown as BadMessageError):
  // where the true beam meets the PSD plane now; nullopt when it does not meet it.
  std::optional<PsdSpot> readSimBeamSpot();
  SimWorldId readSimWorldId();

  // Sends one raw request (checked by checkRequest) and returns the reply, verified to answer
  // the same code with ok = 1. For diagnostics and tests.
  std::string rawRequest(const std::string& request, int expected_fields,
                         std::chrono::milliseconds timeout);

 private:
  struct Io;
  // Throws ConfigError naming every joint whose robot-file limits exceed `bounds`.
  void checkRobotFileAgainst(const std::array<JointLimit, kJointCount>& bounds) const;
  // Formats into the client's own buffer; the view is valid until the next request.
  std::string_view request(int code, std::initializer_list<irc5::Param> params = {});
  std::string_view request(int code, const irc5::Param* params, std::size_t count);
  // The reply looks into the client's own buffer: valid until the next transact().
  irc5::ReplyView transact(std::string_view request, int code, int expected_fields,
                           std::chrono::milliseconds timeout);
  std::chrono::milliseconds jointMoveTimeout(const Joints& from, const Joints& to) const;

  Irc5Options options_;
  std::unique_ptr<Io> io_;
  RobotInfo info_;
  bool have_joints_ = false;
  Joints last_joints_{};
  // The spiral the server holds; valid while search_ready_, which a new connection clears.
  SpotSearch search_;
  bool search_ready_ = false;
};

}  // namespace zerocal
