#include "zerocal/daemon/config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <boost/asio/ip/address.hpp>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <utility>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/change.h"
#include "zerocal/calib/planner.h"
#include "zerocal/cell/kinds.h"
#include "zerocal/error.h"
#include "zerocal/sim/remount.h"
#include "zerocal/sim/world.h"
#include "zerocal/sim/zero_change.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

using settings::Checker;
using settings::Field;
using settings::Fields;
using namespace settings;

std::string where(const std::string& origin, const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return origin;
  return origin + ":" + std::to_string(mark.line + 1);
}

const std::vector<std::pair<std::string, LogLevel>> kLevels = {
    {"trace", LogLevel::kTrace}, {"debug", LogLevel::kDebug}, {"info", LogLevel::kInfo},
    {"warn", LogLevel::kWarn},   {"error", LogLevel::kError}, {"critical", LogLevel::kCritical},
    {"off", LogLevel::kOff}};

Choices<std::string> kindChoices(const std::vector<std::string>& names) {
  Choices<std::string> choices;
  for (const std::string& name : names) choices.emplace_back(name, name);
  return choices;
}

// The whole schema, bound to one configuration: the keys of every section, and those of every
// controller and DAQ kind's own section (each kind declares its own). Adding a key means one
// line here (or in the kind's declare()), one in the checks, one in config/zerocald.yaml and one
// in docs/configuration.md.
std::vector<Field> schema(DaemonConfig& c) {
  std::vector<Field> f;
  f.push_back(
      choiceField<BackendKind>("backend.kind", c.backend.kind,
                               {{"hardware", BackendKind::kHardware}, {"sim", BackendKind::kSim}}));
  f.push_back(pathField("backend.sim_world", c.backend.sim_world));
  f.push_back(seedField("backend.sim_seed", c.backend.sim_seed));
  f.push_back(choiceField<bool>("backend.sim_ideal_world", c.backend.sim_ideal_world,
                                {{"false", false}, {"true", true}}));
  f.push_back(integerField("backend.sim_zero_change_joint", c.backend.sim_zero_change_joint));
  f.push_back(realField("backend.sim_zero_change_deg", c.backend.sim_zero_change_deg));
  f.push_back(vec3Field("backend.sim_psd_moved_mm", c.backend.sim_psd_moved_mm));
  f.push_back(vec3Field("backend.sim_psd_turned_deg", c.backend.sim_psd_turned_deg));
  f.push_back(vec3Field("backend.sim_laser_moved_mm", c.backend.sim_laser_moved_mm));
  f.push_back(vec3Field("backend.sim_laser_turned_deg", c.backend.sim_laser_turned_deg));
  f.push_back(realField("backend.sim_warm_s", c.backend.sim_warm_s));
  f.push_back(realField("backend.sim_gross_rate", c.backend.sim_gross_rate));
  f.push_back(realField("backend.sim_pace", c.backend.sim_pace));
  f.push_back(realField("backend.sim_move_overhead_s", c.backend.sim_move_overhead_s));
  f.push_back(textField("backend.sim_host", c.backend.sim_host));
  f.push_back(integerField("backend.sim_port", c.backend.sim_port));

  auto& k = c.controller;
  f.push_back(choiceField("controller.kind", k.kind, kindChoices(k.sections.names())));
  f.push_back(pathField("controller.robot", k.robot, "builtin"));
  f.push_back(realField("controller.max_step_deg", k.max_step_deg));
  k.sections.declare("controller", f);

  f.push_back(choiceField("daq.kind", c.daq.kind, kindChoices(c.daq.boards.names())));
  f.push_back(realField("daq.sum_threshold_v", c.daq.psd.sum_threshold_v));
  f.push_back(pathField("daq.map_file", c.daq.psd.map_file));
  c.daq.boards.declare("daq", f);

  auto& s = c.servo;
  using servo::ServoStop;
  f.push_back(choiceField<ServoStop>("servo.stop", s.stop,
                                     {{"centre", ServoStop::kCentre}, {"zone", ServoStop::kZone}}));
  f.push_back(realField("servo.tolerance_um", s.tolerance_um));
  f.push_back(realField("servo.max_step_deg", s.max_step_deg));
  f.push_back(integerField("servo.max_iterations", s.max_iterations));
  f.push_back(realField("servo.timeout_s", s.timeout_s));
  f.push_back(realField("servo.settle_s", s.settle_s));
  f.push_back(realField("servo.search_radius_mm", s.search_radius_mm));
  f.push_back(realField("servo.search_step_mm", s.search_step_mm));
  f.push_back(realField("servo.search_time_s", s.search_time_s));
  f.push_back(realField("servo.sweep_speed_mm_s", s.sweep_speed_mm_s));
  f.push_back(realField("servo.sweep_pitch_mm", s.sweep_pitch_mm));
  f.push_back(realField("servo.gain", s.gain));
  f.push_back(realField("servo.damping_mm", s.damping_mm));

  f.push_back(choiceField<PlanKind>("session.plan", c.session.plan,
                                    {{"optimal", PlanKind::kOptimal},
                                     {"I", PlanKind::kI},
                                     {"II", PlanKind::kII},
                                     {"mixed", PlanKind::kMixed},
                                     {"file", PlanKind::kFile}}));
  f.push_back(pathField("session.plan_file", c.session.plan_file));
  f.push_back(integerField("session.poses", c.session.poses));
  f.push_back(integerField("session.placements", c.session.placements));
  f.push_back(vec3Field("session.target_mm", c.session.target_mm));
  f.push_back(vec3Field("session.psd_rpy_deg", c.session.psd_rpy_deg));
  f.push_back(realField("session.joint_repeatability_deg", c.session.joint_repeatability_deg));
  f.push_back(realField("session.psd_noise_mm", c.session.psd_noise_mm));
  f.push_back(realField("session.noise_mm", c.session.noise_mm));
  f.push_back(realField("session.required_accuracy_deg", c.session.required_accuracy_deg));
  f.push_back(realField("session.psd_base_repeatability_mm", c.session.psd_base_repeatability_mm));
  f.push_back(pathField("session.data_dir", c.session.data_dir));

  auto& o = c.control;
  f.push_back(textField("control.bind_address", o.bind_address));
  f.push_back(integerField("control.port", o.port));
  f.push_back(pathField("control.token_file", o.token_file));
  f.push_back(pathField("control.operator_token_file", o.operator_token_file));
  f.push_back(integerField("control.max_clients", o.max_clients));
  f.push_back(integerField("control.max_line_bytes", o.max_line_bytes));
  f.push_back(secondsField("control.idle_timeout_s", o.idle_timeout));
  f.push_back(secondsField("control.write_timeout_s", o.write_timeout));
  f.push_back(kibField("control.max_queued_kib", o.max_queued_bytes));
  f.push_back(integerField("control.max_auth_failures", o.max_auth_failures));
  f.push_back(integerField("control.max_clients_per_peer", o.max_clients_per_peer));
  f.push_back(secondsField("control.auth_timeout_s", o.auth_timeout));
  f.push_back(pathField("control.plan_dir", o.plan_dir));

  auto& w = c.web;
  f.push_back(choiceField<std::optional<bool>>(
      "web.enabled", w.enabled, {{"auto", std::nullopt}, {"false", false}, {"true", true}}));
  f.push_back(textField("web.bind_address", w.bind_address));
  f.push_back(integerField("web.port", w.port));
  f.push_back(choiceField<bool>("web.trusted_network", w.trusted_network,
                                {{"false", false}, {"true", true}}));
  f.push_back(pathField("web.root", w.root));
  f.push_back(pathField("web.tls_certificate", w.tls_certificate));
  f.push_back(pathField("web.tls_key", w.tls_key));
  f.push_back(secondsField("web.session_lifetime_s", w.session_lifetime));

  f.push_back(choiceField("logging.level", c.logging.level, kLevels));
  f.push_back(pathField("logging.directory", c.logging.directory));
  return f;
}

const Field* findField(const std::vector<Field>& fields, const std::string& path) {
  for (const auto& field : fields)
    if (field.path == path) return &field;
  return nullptr;
}

bool isSection(const std::vector<Field>& fields, const std::string& path) {
  const std::string prefix = path + ".";
  for (const auto& field : fields)
    if (field.path.compare(0, prefix.size(), prefix) == 0) return true;
  return false;
}

// An unknown key, and where it went if it is one of a kind's own now: the controller's and the
// board's keys sat directly under controller: and daq: before each kind owned a section.
std::string unknownKey(const std::vector<Field>& fields, const std::string& path) {
  std::string message = "unknown key '" + path + "'";
  // The link and sag tolerances are the robot model's own: a calibrated model carries others.
  if (path == "session.model_length_mm" || path == "session.model_angle_deg" ||
      path == "session.model_sag_deg")
    return message +
           ": the robot model states its tolerances now, in the robot file's "
           "model_tolerance (controller.robot; docs/file-formats.md)";
  const auto dot = path.find('.');
  if (dot == std::string::npos) return message;
  const std::string family = path.substr(0, dot + 1), rest = path.substr(dot + 1);
  for (const Field& field : fields) {
    if (field.path.compare(0, family.size(), family) != 0) continue;
    const auto kind_end = field.path.find('.', family.size());
    if (kind_end == std::string::npos) continue;
    const std::string in_kind = field.path.substr(kind_end + 1);
    if (in_kind == rest || in_kind.compare(0, rest.size() + 1, rest + ".") == 0)
      return message + ": it is '" + field.path.substr(0, kind_end + 1) + rest +
             "' now, in the section of its kind (docs/configuration.md)";
  }
  return message;
}

struct Layer {
  const std::vector<Field>& fields;
  const std::string& origin;
  const std::string& base_dir;
  ConfigOrigins& origins;
  std::vector<std::string>& problems;
  bool lines = true;  // a file has line numbers, the command line has not

  std::string at(const YAML::Node& node) const { return lines ? where(origin, node) : origin; }

  // `key` locates the problem: the key's line is where a reader looks, also when the value is
  // missing or a block list starting on the next line.
  void setLeaf(const Field& field, const YAML::Node& key, const YAML::Node& value) {
    const std::string error = field.set(value, base_dir);
    if (error.empty())
      origins[field.path] = at(key);
    else
      problems.push_back(at(key) + ": " + field.path + ": " + error);
  }

  void walk(const YAML::Node& node, const std::string& prefix) {
    // A section whose keys are all commented out is empty, not wrong.
    if (node.IsNull()) return;
    if (!node.IsMap()) {
      problems.push_back(at(node) + ": " + (prefix.empty() ? "the document" : prefix) +
                         ": expected a mapping, got " + describe(node));
      return;
    }
    for (const auto& entry : node) {
      if (!entry.first.IsScalar()) {
        problems.push_back(at(entry.first) + ": a key must be a plain word");
        continue;
      }
      const std::string path = (prefix.empty() ? "" : prefix + ".") + entry.first.Scalar();
      if (const Field* field = findField(fields, path))
        setLeaf(*field, entry.first, entry.second);
      else if (isSection(fields, path))
        walk(entry.second, path);
      else
        problems.push_back(at(entry.first) + ": " + unknownKey(fields, path));
    }
  }
};

// The daq section's checks, shared by zerocald and `zerocal-lab psd` (loadDaqSection): its own
// keys, and its board's section.
void checkDaq(const DaqConfig& d, bool real_cell, Checker& check) {
  // An empty map_file is refused by the hardware backend when it starts, not here: the
  // compiled-in defaults stay a valid configuration for the simulated cell.
  if (!d.psd.map_file.empty()) check.fileExists("daq.map_file", d.psd.map_file);
  check.range("daq.sum_threshold_v", d.psd.sum_threshold_v, 0.0, 20.0);
  if (const DaqSettings* board = d.boards.find(d.kind))
    board->check("daq." + d.kind + ".", real_cell, check);
  else
    check.fail("daq.kind",
               "'" + d.kind + "' is not a board zerocal can read (" + kinds::daqKindNames() + ")");
}

std::string readFile(const fs::path& path, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot be read";
    return {};
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

void applyConfigYaml(DaemonConfig& config, const std::string& yaml_text, const std::string& origin,
                     const std::string& base_dir, ConfigOrigins& origins,
                     std::vector<std::string>& problems) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    problems.push_back(origin + (e.mark.is_null() ? "" : ":" + std::to_string(e.mark.line + 1)) +
                       ": not valid YAML: " + e.msg);
    return;
  }
  if (root.IsNull()) return;  // an empty or all-comment file changes nothing
  const auto fields = schema(config);
  Layer{fields, origin, base_dir, origins, problems}.walk(root, "");
}

void applyConfigOverride(DaemonConfig& config, const std::string& assignment,
                         ConfigOrigins& origins, std::vector<std::string>& problems) {
  const std::string origin = "command line '" + assignment + "'";
  const auto equals = assignment.find('=');
  if (equals == std::string::npos || equals == 0) {
    problems.push_back(origin + ": expected section.key=value");
    return;
  }
  const std::string path = assignment.substr(0, equals);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(equals + 1));
  } catch (const YAML::Exception& e) {
    problems.push_back(origin + ": " + path + ": not valid YAML: " + e.msg);
    return;
  }
  const auto fields = schema(config);
  const std::string base_dir = fs::current_path().string();
  Layer layer{fields, origin, base_dir, origins, problems, false};
  if (const Field* field = findField(fields, path))
    layer.setLeaf(*field, value, value);
  else if (isSection(fields, path))
    layer.walk(value, path);
  else
    problems.push_back(origin + ": " + unknownKey(fields, path));
}

std::vector<std::string> validateDaemonConfig(const DaemonConfig& c, const ConfigOrigins& origins) {
  std::vector<std::string> problems;
  Checker check(origins, problems);

  const auto& b = c.backend;
  check.range("backend.sim_pace", b.sim_pace, 0.0, 10.0);
  check.range("backend.sim_gross_rate", b.sim_gross_rate, 0.0, 1.0);
  check.range("backend.sim_move_overhead_s", b.sim_move_overhead_s, 0.0, 60.0);
  check.range("backend.sim_warm_s", b.sim_warm_s, 0.0, kMaxWarmS);
  if (b.kind == BackendKind::kSim) {
    if (!b.sim_world.empty() && b.sim_seed)
      check.fail("backend.sim_seed", "give backend.sim_world or backend.sim_seed, not both");
    if (!b.sim_world.empty()) check.fileExists("backend.sim_world", b.sim_world);
    const std::string change =
        zeroChangeProblem(ZeroChange{b.sim_zero_change_joint, b.sim_zero_change_deg});
    if (!change.empty())
      check.fail(b.sim_zero_change_joint == 0 ||
                         (b.sim_zero_change_joint >= 2 && b.sim_zero_change_joint <= 5)
                     ? "backend.sim_zero_change_deg"
                     : "backend.sim_zero_change_joint",
                 change);
    else if (b.sim_zero_change_joint != 0 && !b.sim_host.empty())
      check.fail("backend.sim_zero_change_joint",
                 "an external zerocal-sim simulates its own world: change a zero on the "
                 "in-process simulated cell (leave backend.sim_host unset), or give zerocal-sim a "
                 "world file with the changed offsets");
    const Remount psd{b.sim_psd_moved_mm, b.sim_psd_turned_deg};
    const Remount laser{b.sim_laser_moved_mm, b.sim_laser_turned_deg};
    const std::pair<const char*, std::string> remount_problems[] = {
        {"backend.sim_psd_moved_mm", remountMoveProblem(psd)},
        {"backend.sim_psd_turned_deg", remountTurnProblem(psd)},
        {"backend.sim_laser_moved_mm", remountMoveProblem(laser)},
        {"backend.sim_laser_turned_deg", remountTurnProblem(laser)}};
    for (const auto& [key, problem] : remount_problems)
      if (!problem.empty()) check.fail(key, problem);
    if ((psd.any() || laser.any()) && !b.sim_host.empty())
      check.fail(psd.any() ? "backend.sim_psd_moved_mm" : "backend.sim_laser_moved_mm",
                 "an external zerocal-sim simulates its own world: re-mount the PSD or the laser "
                 "on the in-process simulated cell (leave backend.sim_host unset), or give "
                 "zerocal-sim a world file with them where they are");
    if (b.sim_warm_s != 0 && !b.sim_host.empty())
      check.fail("backend.sim_warm_s",
                 "an external zerocal-sim keeps its own clock: warm the arm on the in-process "
                 "simulated cell (leave backend.sim_host unset)");
    if (b.sim_host.empty() != (b.sim_port == 0))
      check.fail(b.sim_host.empty() ? "backend.sim_port" : "backend.sim_host",
                 "an external zerocal-sim needs both backend.sim_host and backend.sim_port");
  }

  const auto& k = c.controller;
  const bool real_cell = b.kind == BackendKind::kHardware;
  if (k.robot != "builtin") check.fileExists("controller.robot", k.robot);
  // A calibration never needs one move larger than this; a larger step is a typing error.
  check.positive("controller.max_step_deg", k.max_step_deg, 45.0);
  const ControllerSettings* controller = k.sections.find(k.kind);
  if (controller)
    controller->check("controller." + k.kind + ".", real_cell, check);
  else
    check.fail("controller.kind", "'" + k.kind + "' is not a controller zerocal can drive (" +
                                      kinds::controllerKindNames() + ")");

  checkDaq(c.daq, real_cell, check);

  const auto& s = c.servo;
  check.positive("servo.tolerance_um", s.tolerance_um, 1000.0);
  // A servo step moves the spot a few mm; 5 deg moves it by tens of mm at 1 m.
  check.positive("servo.max_step_deg", s.max_step_deg, 5.0);
  if (s.max_step_deg > k.max_step_deg)
    check.fail("servo.max_step_deg", numberText(s.max_step_deg) +
                                         " exceeds controller.max_step_deg (" +
                                         numberText(k.max_step_deg) + ")");
  check.range("servo.max_iterations", s.max_iterations, 1, 100000);
  check.positive("servo.timeout_s", s.timeout_s, 3600.0);
  check.range("servo.settle_s", s.settle_s, 0.0, 60.0);
  check.positive("servo.search_radius_mm", s.search_radius_mm, 100.0);
  check.positive("servo.search_step_mm", s.search_step_mm, 100.0);
  if (s.search_step_mm > s.search_radius_mm)
    check.fail("servo.search_step_mm", numberText(s.search_step_mm) +
                                           " exceeds servo.search_radius_mm (" +
                                           numberText(s.search_radius_mm) + ")");
  check.positive("servo.search_time_s", s.search_time_s, 3600.0);
  check.range("servo.sweep_speed_mm_s", s.sweep_speed_mm_s, 0.0, 1000.0);
  if (controller) {
    const double linear = controller->motion().linear_speed_mm_s;
    if (s.sweep_speed_mm_s > linear)
      check.fail("servo.sweep_speed_mm_s",
                 numberText(s.sweep_speed_mm_s) + " exceeds the linear speed of the controller." +
                     k.kind + " section (" + numberText(linear) + " mm/s)");
  }
  // Over 11.4 mm two turns of the spiral can pass either side of the lit disk (5.7 mm radius).
  check.positive("servo.sweep_pitch_mm", s.sweep_pitch_mm, 11.0);
  // Above 1 the step overshoots a right Jacobian; the servo is stable for any gain in (0, 1].
  check.positive("servo.gain", s.gain, 1.0);
  // Damping of 1 (mm/deg)^2 already shortens every step by about half at the usual 1 mm/deg.
  check.range("servo.damping_mm", s.damping_mm, 0.0, 1.0);

  const auto& n = c.session;
  if (n.plan == PlanKind::kFile) {
    if (n.plan_file.empty())
      check.fail("session.plan_file", "required by session.plan: file");
    else
      check.fileExists("session.plan_file", n.plan_file);
  } else if (!n.plan_file.empty()) {
    check.fail("session.plan_file", "only used with session.plan: file");
  }
  check.range("session.poses", n.poses, kMinimumPoses, kMaxPlanPoses);
  check.range("session.placements", n.placements, 1, kMaxDefaultPlacements);
  if (n.placements > 1 && n.plan == PlanKind::kFile)
    check.fail("session.placements",
               "not used with session.plan: file (the plan file's "
               "placement column says where each pose is)");
  check.positive("session.noise_mm", n.noise_mm, 10.0);
  // 0.1 deg per joint would be a loose joint, not repeatability; 0 chooses noise_mm.
  check.range("session.joint_repeatability_deg", n.joint_repeatability_deg, 0.0, 0.1);
  check.range("session.psd_noise_mm", n.psd_noise_mm, 0.0, 1.0);
  // Beyond a degree the offsets would be mastering errors, not a calibration's business.
  check.positive("session.required_accuracy_deg", n.required_accuracy_deg, 1.0);
  check.range("session.psd_base_repeatability_mm", n.psd_base_repeatability_mm, 0.0,
              kMostBaseRepeatabilityMm);
  if (n.data_dir.empty()) check.fail("session.data_dir", "must not be empty");

  const auto& o = c.control;
  const auto seconds = [](std::chrono::milliseconds ms) {
    return std::chrono::duration<double>(ms).count();
  };
  boost::system::error_code ec;
  const auto address = boost::asio::ip::make_address(o.bind_address, ec);
  if (ec) {
    check.fail("control.bind_address", "'" + o.bind_address + "' is not an IP address");
  } else if (!address.is_loopback() && o.token_file.empty()) {
    check.fail("control.token_file", "required when control.bind_address (" + o.bind_address +
                                         ") is reachable from other machines");
  }
  check.range("control.max_clients", static_cast<double>(o.max_clients), 1, 10000);
  check.range("control.max_line_bytes", static_cast<double>(o.max_line_bytes), 1024, 16 << 20);
  // Below a second a terminal could not send its next line in time.
  check.range("control.idle_timeout_s", seconds(o.idle_timeout), 1.0, 86400.0);
  check.positive("control.write_timeout_s", seconds(o.write_timeout), 3600.0);
  check.range("control.max_queued_kib", static_cast<double>(o.max_queued_bytes / 1024), 64,
              1 << 20);
  check.range("control.max_auth_failures", o.max_auth_failures, 1, 100);
  check.range("control.max_clients_per_peer", static_cast<double>(o.max_clients_per_peer), 1,
              static_cast<double>(o.max_clients));
  check.range("control.auth_timeout_s", seconds(o.auth_timeout), 0.5, 600.0);
  if (!o.token_file.empty()) check.fileExists("control.token_file", o.token_file);
  if (!o.operator_token_file.empty()) {
    check.fileExists("control.operator_token_file", o.operator_token_file);
    if (o.token_file.empty())
      check.fail("control.operator_token_file", "needs control.token_file (the engineer's) too");
    else if (o.operator_token_file == o.token_file)
      check.fail("control.operator_token_file",
                 "is control.token_file: an operator's login must have a token of its own");
  }

  const auto& w = c.web;
  const auto web_address = boost::asio::ip::make_address(w.bind_address, ec);
  if (ec)
    check.fail("web.bind_address", "'" + w.bind_address + "' is not an IP address");
  else if (!web_address.is_loopback() && w.tls_certificate.empty() && !w.trusted_network)
    check.fail("web.bind_address",
               w.bind_address +
                   " is reachable from other machines, and the web terminal has no TLS: the "
                   "token and the login cookie would cross the network in clear. Set "
                   "web.tls_certificate and web.tls_key, keep 127.0.0.1 (reach it through an "
                   "SSH tunnel, docs/web.md), or set web.trusted_network: true for a network "
                   "only the cell's terminals are on");
  if (w.tls_certificate.empty() != w.tls_key.empty())
    check.fail(w.tls_key.empty() ? "web.tls_key" : "web.tls_certificate",
               "web.tls_certificate and web.tls_key go together: TLS needs both");
  if (!w.tls_certificate.empty()) check.fileExists("web.tls_certificate", w.tls_certificate);
  if (!w.tls_key.empty()) check.fileExists("web.tls_key", w.tls_key);
  if (webEnabled(c) && w.port != 0 && w.port == o.port && w.bind_address == o.bind_address)
    check.fail("web.port", std::to_string(w.port) + " is control.port's as well");
  // Under a minute a technician would be asked for the token during a session.
  check.range("web.session_lifetime_s", seconds(w.session_lifetime), 60.0, 7 * 86400.0);
  if (!w.root.empty()) {
    std::error_code fec;
    if (!fs::is_regular_file(fs::path(w.root) / "index.html", fec))
      check.fail("web.root", "no index.html in " + w.root);
  }

  // The diagnostic log and the measured data are kept apart (house style).
  if (!c.logging.directory.empty() && !n.data_dir.empty() &&
      fs::path(c.logging.directory).lexically_normal() == fs::path(n.data_dir).lexically_normal())
    check.fail("logging.directory", "must differ from session.data_dir");
  return problems;
}

DaemonConfig loadDaemonConfig(const ConfigSources& sources) {
  DaemonConfig config;
  ConfigOrigins origins;
  std::vector<std::string> problems;

  auto applyFile = [&](const fs::path& path) {
    std::string error;
    const std::string text = readFile(path, error);
    if (!error.empty()) {
      problems.push_back(path.string() + ": " + error);
      return;
    }
    applyConfigYaml(config, text, path.string(), fs::absolute(path).parent_path().string(), origins,
                    problems);
  };

  std::error_code ec;
  if (fs::exists(sources.config_path, ec))
    applyFile(sources.config_path);
  else if (sources.config_path_explicit)
    problems.push_back(sources.config_path + ": no such file");

  if (fs::is_directory(sources.drop_in_dir, ec)) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(sources.drop_in_dir, ec))
      if (entry.path().extension() == ".yaml" && !entry.is_directory()) files.push_back(entry);
    if (ec) problems.push_back(sources.drop_in_dir + ": cannot be listed: " + ec.message());
    std::sort(files.begin(), files.end(),
              [](const fs::path& a, const fs::path& o) { return a.filename() < o.filename(); });
    for (const auto& file : files) applyFile(file);
  } else if (fs::exists(sources.drop_in_dir, ec)) {
    problems.push_back(sources.drop_in_dir + ": not a folder");
  } else if (sources.drop_in_dir_explicit) {
    problems.push_back(sources.drop_in_dir + ": no such folder");
  }

  for (const auto& assignment : sources.overrides)
    applyConfigOverride(config, assignment, origins, problems);

  auto invalid = validateDaemonConfig(config, origins);
  problems.insert(problems.end(), invalid.begin(), invalid.end());
  if (!problems.empty()) throw ConfigError("configuration", std::move(problems));
  return config;
}

nlohmann::json configToJson(const DaemonConfig& config) {
  DaemonConfig copy = config;
  // The sections of the kinds not used are defaults nobody chose: the snapshot is what ran.
  const auto ofAnotherKind = [&config](const std::string& path) {
    const auto other = [&path](const std::string& family, const std::string& used,
                               const std::vector<std::string>& kinds) {
      for (const std::string& kind : kinds)
        if (kind != used && path.rfind(family + "." + kind + ".", 0) == 0) return true;
      return false;
    };
    return other("controller", config.controller.kind, config.controller.sections.names()) ||
           other("daq", config.daq.kind, config.daq.boards.names());
  };
  Json out = Json::object();
  for (const auto& field : schema(copy)) {
    if (ofAnotherKind(field.path)) continue;
    Json* at = &out;
    std::string::size_type start = 0, dot;
    while ((dot = field.path.find('.', start)) != std::string::npos) {
      at = &(*at)[field.path.substr(start, dot - start)];
      start = dot + 1;
    }
    (*at)[field.path.substr(start)] = field.get();
  }
  return out;
}

std::vector<std::string> configKeys() {
  DaemonConfig scratch;
  std::vector<std::string> keys;
  for (const auto& field : schema(scratch)) keys.push_back(field.path);
  return keys;
}

DaqConfig loadDaqSection(const std::string& path) {
  std::vector<std::string> problems;
  std::string error;
  const std::string text = readFile(path, error);
  if (!error.empty()) throw ConfigError(path, {error});
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path,
                      {(e.mark.is_null() ? "" : "line " + std::to_string(e.mark.line + 1) + ": ") +
                       "not valid YAML: " + e.msg});
  }
  if (!root.IsMap() || !root["daq"]) {
    if (root.IsMap() && root["psd"])
      throw ConfigError(
          path,
          {"the psd: section of earlier versions is now the daq: section of zerocald's "
           "configuration (docs/configuration.md): samples is usb-1408fs.samples_per_reading, "
           "rate_hz usb-1408fs.scan_rate_hz, a channel (under usb-1408fs.channels) has "
           "its input as its number, range_v: 5 is range: 5V; "
           "sum_off_threshold_v is 0.8 x sum_threshold_v, and the map is named by map_file"});
    throw ConfigError(path, {"the file must hold a 'daq:' section at its top level"});
  }
  DaemonConfig config;
  ConfigOrigins origins;
  const auto fields = schema(config);
  const std::string base_dir = fs::absolute(path).parent_path().string();
  Layer{fields, path, base_dir, origins, problems}.walk(root["daq"], "daq");
  Checker check(origins, problems);
  checkDaq(config.daq, /*real_cell=*/true, check);
  if (!problems.empty()) throw ConfigError(path, std::move(problems));
  return config.daq;
}

const ControllerSettings& ControllerConfig::section() const {
  if (const ControllerSettings* found = sections.find(kind)) return *found;
  throw ConfigError("controller.kind", {"'" + kind + "' is not a controller zerocal can drive (" +
                                        kinds::controllerKindNames() + ")"});
}

const DaqSettings& DaqConfig::board() const {
  if (const DaqSettings* found = boards.find(kind)) return *found;
  throw ConfigError("daq.kind", {"'" + kind + "' is not a board zerocal can read (" +
                                 kinds::daqKindNames() + ")"});
}

bool webEnabled(const DaemonConfig& config) {
  return config.web.enabled.value_or(config.backend.kind == BackendKind::kSim);
}

std::string logLevelName(LogLevel level) {
  for (const auto& [name, value] : kLevels)
    if (value == level) return name;
  return "?";
}

}  // namespace zerocal
