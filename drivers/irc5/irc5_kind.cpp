#include "zerocal/irc5/irc5_kind.h"

#include "zerocal/irc5/motion_time.h"

namespace zerocal::irc5 {

Irc5Options configuredDefaults() {
  Irc5Options o;
  o.speed_tcp_mm_s = 250.0;
  o.speed_ori_deg_s = 100.0;
  o.limit_margin_deg = 1.0;
  return o;
}

void Irc5Settings::declare(const std::string& prefix, settings::Fields& f) {
  using namespace settings;
  auto& l = options;
  f.push_back(textField(prefix + "host", l.host));
  f.push_back(integerField(prefix + "port", l.port));
  f.push_back(millisField(prefix + "connect_timeout_ms", l.connect_timeout));
  f.push_back(millisField(prefix + "request_timeout_ms", l.request_timeout));
  f.push_back(realField(prefix + "move_timeout_factor", l.move_timeout_factor));
  f.push_back(millisField(prefix + "move_timeout_margin_ms", l.move_timeout_margin));
  f.push_back(realField(prefix + "speed_tcp_mm_s", l.speed_tcp_mm_s));
  f.push_back(realField(prefix + "speed_ori_deg_s", l.speed_ori_deg_s));
  f.push_back(realField(prefix + "limit_margin_deg", l.limit_margin_deg));
  f.push_back(integerField(prefix + "reconnect_attempts", l.reconnect_attempts));
  f.push_back(millisField(prefix + "restart_timeout_ms", l.restart_timeout));
}

void Irc5Settings::check(const std::string& prefix, bool real_cell,
                         settings::Checker& check) const {
  const auto& l = options;
  if (real_cell && l.host.empty())
    check.fail(prefix + "host", "must not be empty with backend.kind: hardware");
  if (l.port == 0) check.fail(prefix + "port", "must be 1..65535");
  check.positive(prefix + "connect_timeout_ms", l.connect_timeout.count(), 600000);
  check.positive(prefix + "request_timeout_ms", l.request_timeout.count(), 600000);
  check.range(prefix + "move_timeout_factor", l.move_timeout_factor, 1.0, 100.0);
  check.range(prefix + "move_timeout_margin_ms", l.move_timeout_margin.count(), 0, 600000);
  // 7000 mm/s and 1000 deg/s are above any IRC5 robot's maximum: beyond them a value is a typo.
  check.positive(prefix + "speed_tcp_mm_s", l.speed_tcp_mm_s, 7000.0);
  check.positive(prefix + "speed_ori_deg_s", l.speed_ori_deg_s, 1000.0);
  check.range(prefix + "limit_margin_deg", l.limit_margin_deg, 0.0, 30.0);
  check.range(prefix + "reconnect_attempts", l.reconnect_attempts, 0, 1000);
  // The wait for a restart shows no progress: it must stay below the worker's 120 s stall limit.
  check.positive(prefix + "restart_timeout_ms", l.restart_timeout.count(), 110000);
}

ControllerMotion Irc5Settings::motion() const {
  ControllerMotion m;
  // Only the motion differs between two orders of the same poses: every move has the same fixed
  // cost and settling.
  m.travel_s = [tcp = options.speed_tcp_mm_s, ori = options.speed_ori_deg_s](
                   const Robot& robot, const Joints& from, const Joints& to) {
    return jointMoveTime(robot, from, to, tcp, ori, MotionCosts{}).motion_s;
  };
  m.settle_s = MotionCosts{}.settle_s;
  m.limit_margin_deg = options.limit_margin_deg;
  m.linear_speed_mm_s = options.speed_tcp_mm_s;
  m.restart_timeout = options.restart_timeout;
  return m;
}

Irc5Options Irc5Settings::linkOptions(const Robot& robot, const LinkEndpoint* endpoint) const {
  Irc5Options o = options;
  o.robot = robot;
  if (endpoint) {
    o.host = endpoint->host;
    o.port = endpoint->port;
    o.backoff_initial = endpoint->backoff_initial;
  }
  return o;
}

std::unique_ptr<ControllerConnection> Irc5Settings::link(const Robot& robot,
                                                         const LinkEndpoint* endpoint) const {
  return std::make_unique<Irc5Client>(linkOptions(robot, endpoint));
}

ControllerKind controllerKind() {
  return {"irc5", "ABB IRC5 through zerocal's RAPID socket server",
          [] { return std::make_unique<Irc5Settings>(); }};
}

}  // namespace zerocal::irc5
