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
#include "zerocal/calib/planner.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// One key of the schema. The setter parses completely before it assigns, so a wrong value never
// leaves a half-changed member behind; it returns the reason for refusing, or "".
struct Field {
  std::string path;
  std::function<std::string(const YAML::Node&, const std::string& base_dir)> set;
  std::function<Json()> get;
};

std::string describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "no value";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    default:
      return "'" + node.Scalar() + "'";
  }
}

std::string where(const std::string& origin, const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return origin;
  return origin + ":" + std::to_string(mark.line + 1);
}

// A text value goes into every session's session.json (configToJson): it must be what JSON can
// hold, UTF-8, or that snapshot would fail at every session start. Checked by the same serializer.
bool isUtf8(const std::string& text) {
  try {
    Json(text).dump();
    return true;
  } catch (const Json::type_error&) {
    return false;
  }
}

bool parseInteger(const YAML::Node& node, long long& value) {
  if (!node.IsScalar()) return false;
  const std::string& text = node.Scalar();
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  value = std::strtoll(text.c_str(), &end, 10);
  return errno == 0 && end == text.c_str() + text.size();
}

bool parseReal(const YAML::Node& node, double& value) {
  if (!node.IsScalar()) return false;
  const std::string& text = node.Scalar();
  if (text.empty()) return false;
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size();
}

template <class T>
Field integerField(std::string path, T& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            long long value = 0;
            if (!parseInteger(node, value)) return "expected an integer, got " + describe(node);
            // Compared as long long: the widest member types (std::size_t) are capped there.
            constexpr long long lo = static_cast<long long>(std::numeric_limits<T>::min());
            constexpr long long hi =
                std::numeric_limits<T>::max() >
                        static_cast<unsigned long long>(std::numeric_limits<long long>::max())
                    ? std::numeric_limits<long long>::max()
                    : static_cast<long long>(std::numeric_limits<T>::max());
            if (value < lo || value > hi)
              return node.Scalar() + " does not fit (" + std::to_string(lo) + ".." +
                     std::to_string(hi) + ")";
            target = static_cast<T>(value);
            return {};
          },
          [&target] { return Json(target); }};
}

Field millisField(std::string path, std::chrono::milliseconds& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            long long value = 0;
            if (!parseInteger(node, value))
              return "expected an integer (milliseconds), got " + describe(node);
            target = std::chrono::milliseconds(value);
            return {};
          },
          [&target] { return Json(target.count()); }};
}

// A key in seconds (a number) for a member in milliseconds; fractions of a millisecond are cut
// off, as the timers that use the member count whole milliseconds.
Field secondsField(std::string path, std::chrono::milliseconds& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            double value = 0;
            if (!parseReal(node, value))
              return "expected a number (seconds), got " + describe(node);
            if (!std::isfinite(value) || std::abs(value) > 1e9)
              return "expected a finite number of seconds, got " + describe(node);
            target = std::chrono::duration_cast<std::chrono::milliseconds>(
                std::chrono::duration<double>(value));
            return {};
          },
          [&target] { return Json(std::chrono::duration<double>(target).count()); }};
}

// A key in KiB for a member in bytes.
Field kibField(std::string path, std::size_t& target_bytes) {
  return {std::move(path),
          [&target_bytes](const YAML::Node& node, const std::string&) -> std::string {
            long long value = 0;
            if (!parseInteger(node, value))
              return "expected an integer (KiB), got " + describe(node);
            if (value < 0 || value > (1LL << 40))
              return node.Scalar() + " does not fit (0.." + std::to_string(1LL << 40) + ")";
            target_bytes = static_cast<std::size_t>(value) * 1024;
            return {};
          },
          [&target_bytes] { return Json(static_cast<long long>(target_bytes / 1024)); }};
}

Field realField(std::string path, double& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            double value = 0;
            if (!parseReal(node, value)) return "expected a number, got " + describe(node);
            if (!std::isfinite(value)) return "expected a finite number, got " + describe(node);
            target = value;
            return {};
          },
          [&target] { return Json(target); }};
}

Field textField(std::string path, std::string& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            if (!node.IsScalar()) return "expected a text, got " + describe(node);
            if (!isUtf8(node.Scalar())) return "expected a text in UTF-8";
            target = node.Scalar();
            return {};
          },
          [&target] { return Json(target); }};
}

// A file or folder name; relative names are resolved against the folder of the file that wrote
// them, so a drop-in can name a neighbour. `keep` is a word that is not a path ("builtin").
Field pathField(std::string path, std::string& target, std::string keep = {}) {
  return {std::move(path),
          [&target, keep](const YAML::Node& node, const std::string& base_dir) -> std::string {
            if (!node.IsScalar()) return "expected a path, got " + describe(node);
            if (!isUtf8(node.Scalar())) return "expected a path in UTF-8";
            std::string value = node.Scalar();
            if (!value.empty() && value != keep && fs::path(value).is_relative())
              value = (fs::path(base_dir.empty() ? fs::current_path() : fs::path(base_dir)) / value)
                          .lexically_normal()
                          .string();
            target = value;
            return {};
          },
          [&target] { return Json(target); }};
}

template <class E>
Field choiceField(std::string path, E& target, std::vector<std::pair<std::string, E>> choices) {
  auto name_of = [choices](E value) {
    for (const auto& [name, e] : choices)
      if (e == value) return name;
    return std::string("?");
  };
  return {std::move(path),
          [&target, choices](const YAML::Node& node, const std::string&) -> std::string {
            std::string list;
            for (const auto& [name, e] : choices) {
              if (node.IsScalar() && node.Scalar() == name) {
                target = e;
                return {};
              }
              list += (list.empty() ? "" : ", ") + name;
            }
            return "expected one of " + list + ", got " + describe(node);
          },
          [&target, name_of] { return Json(name_of(target)); }};
}

Field seedField(std::string path, std::optional<std::uint64_t>& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            // null is a value here: a later layer can take back an earlier layer's seed.
            if (node.IsNull()) {
              target.reset();
              return {};
            }
            long long value = 0;
            if (!parseInteger(node, value) || value < 0)
              return "expected a non-negative integer or null, got " + describe(node);
            target = static_cast<std::uint64_t>(value);
            return {};
          },
          [&target] { return target ? Json(*target) : Json(nullptr); }};
}

Field vec3Field(std::string path, std::array<double, 3>& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            const std::string expected = "expected a list of 3 numbers, got ";
            if (!node.IsSequence() || node.size() != 3) {
              return expected + (node.IsSequence() ? "a list of " + std::to_string(node.size())
                                                   : describe(node));
            }
            std::array<double, 3> value{};
            for (std::size_t i = 0; i < 3; ++i)
              if (!parseReal(node[i], value[i]) || !std::isfinite(value[i]))
                return expected + describe(node[i]) + " at position " + std::to_string(i + 1);
            target = value;
            return {};
          },
          [&target] { return Json(target); }};
}

const std::vector<std::pair<std::string, usb1408fs::Range>> kRanges = {
    {"20V", usb1408fs::Range::kBip20V},     {"10V", usb1408fs::Range::kBip10V},
    {"5V", usb1408fs::Range::kBip5V},       {"4V", usb1408fs::Range::kBip4V},
    {"2.5V", usb1408fs::Range::kBip2_5V},   {"2V", usb1408fs::Range::kBip2V},
    {"1.25V", usb1408fs::Range::kBip1_25V}, {"1V", usb1408fs::Range::kBip1V}};

const std::vector<std::pair<std::string, LogLevel>> kLevels = {
    {"trace", LogLevel::kTrace}, {"debug", LogLevel::kDebug}, {"info", LogLevel::kInfo},
    {"warn", LogLevel::kWarn},   {"error", LogLevel::kError}, {"critical", LogLevel::kCritical},
    {"off", LogLevel::kOff}};

void addChannel(std::vector<Field>& fields, const std::string& name, usb1408fs::Channel& channel) {
  const std::string prefix = "daq.channels." + name + ".";
  fields.push_back(integerField(prefix + "number", channel.number));
  fields.push_back(
      choiceField<usb1408fs::InputMode>(prefix + "mode", channel.mode,
                                        {{"differential", usb1408fs::InputMode::kDifferential},
                                         {"single_ended", usb1408fs::InputMode::kSingleEnded}}));
  fields.push_back(choiceField(prefix + "range", channel.range, kRanges));
}

// The whole schema, bound to one configuration. Adding a key means one line here, one in
// validate(), one in config/zerocald.yaml and one in docs/configuration.md.
std::vector<Field> schema(DaemonConfig& c) {
  std::vector<Field> f;
  f.push_back(
      choiceField<BackendKind>("backend.kind", c.backend.kind,
                               {{"hardware", BackendKind::kHardware}, {"sim", BackendKind::kSim}}));
  f.push_back(pathField("backend.sim_world", c.backend.sim_world));
  f.push_back(seedField("backend.sim_seed", c.backend.sim_seed));
  f.push_back(choiceField<bool>("backend.sim_ideal_world", c.backend.sim_ideal_world,
                                {{"false", false}, {"true", true}}));
  f.push_back(realField("backend.sim_gross_rate", c.backend.sim_gross_rate));
  f.push_back(realField("backend.sim_pace", c.backend.sim_pace));
  f.push_back(realField("backend.sim_move_overhead_s", c.backend.sim_move_overhead_s));
  f.push_back(textField("backend.sim_host", c.backend.sim_host));
  f.push_back(integerField("backend.sim_port", c.backend.sim_port));

  auto& k = c.controller;
  f.push_back(
      choiceField<ControllerKind>("controller.kind", k.kind, {{"irc5", ControllerKind::kIrc5}}));
  f.push_back(pathField("controller.robot", k.robot, "builtin"));
  auto& l = k.irc5;
  f.push_back(textField("controller.host", l.host));
  f.push_back(integerField("controller.port", l.port));
  f.push_back(millisField("controller.connect_timeout_ms", l.connect_timeout));
  f.push_back(millisField("controller.request_timeout_ms", l.request_timeout));
  f.push_back(realField("controller.move_timeout_factor", l.move_timeout_factor));
  f.push_back(millisField("controller.move_timeout_margin_ms", l.move_timeout_margin));
  f.push_back(realField("controller.speed_tcp_mm_s", l.speed_tcp_mm_s));
  f.push_back(realField("controller.speed_ori_deg_s", l.speed_ori_deg_s));
  f.push_back(realField("controller.limit_margin_deg", l.limit_margin_deg));
  f.push_back(realField("controller.max_step_deg", k.max_step_deg));
  f.push_back(integerField("controller.reconnect_attempts", l.reconnect_attempts));
  f.push_back(millisField("controller.restart_timeout_ms", l.restart_timeout));

  using psd::DaqKind;
  f.push_back(choiceField<DaqKind>("daq.kind", c.daq.kind, {{"usb-1408fs", DaqKind::kUsb1408fs}}));
  f.push_back(textField("daq.serial", c.daq.serial));
  addChannel(f, "x", c.daq.channels.x);
  addChannel(f, "y", c.daq.channels.y);
  addChannel(f, "sum", c.daq.channels.sum);
  f.push_back(realField("daq.scan_rate_hz", c.daq.scan_rate_hz));
  f.push_back(integerField("daq.samples_per_reading", c.daq.samples_per_reading));
  f.push_back(realField("daq.sum_threshold_v", c.daq.sum_threshold_v));
  f.push_back(pathField("daq.map_file", c.daq.map_file));

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
  f.push_back(realField("session.noise_mm", c.session.noise_mm));
  f.push_back(realField("session.required_accuracy_deg", c.session.required_accuracy_deg));
  f.push_back(realField("session.model_length_mm", c.session.model_length_mm));
  f.push_back(realField("session.model_angle_deg", c.session.model_angle_deg));
  f.push_back(realField("session.model_sag_deg", c.session.model_sag_deg));
  f.push_back(pathField("session.data_dir", c.session.data_dir));

  auto& o = c.control;
  f.push_back(textField("control.bind_address", o.bind_address));
  f.push_back(integerField("control.port", o.port));
  f.push_back(pathField("control.token_file", o.token_file));
  f.push_back(integerField("control.max_clients", o.max_clients));
  f.push_back(integerField("control.max_line_bytes", o.max_line_bytes));
  f.push_back(secondsField("control.idle_timeout_s", o.idle_timeout));
  f.push_back(secondsField("control.write_timeout_s", o.write_timeout));
  f.push_back(kibField("control.max_queued_kib", o.max_queued_bytes));
  f.push_back(integerField("control.max_auth_failures", o.max_auth_failures));
  f.push_back(integerField("control.max_clients_per_peer", o.max_clients_per_peer));
  f.push_back(secondsField("control.auth_timeout_s", o.auth_timeout));
  f.push_back(pathField("control.plan_dir", o.plan_dir));

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
        problems.push_back(at(entry.first) + ": unknown key '" + path + "'");
    }
  }
};

template <class T>
std::string str(T value) {
  std::ostringstream s;
  s << value;
  return s.str();
}

class Checker {
 public:
  Checker(const ConfigOrigins& origins, std::vector<std::string>& problems)
      : origins_(origins), problems_(problems) {}

  void fail(const std::string& path, const std::string& message) {
    const auto it = origins_.find(path);
    problems_.push_back((it == origins_.end() ? std::string("default") : it->second) + ": " + path +
                        ": " + message);
  }
  // lo <= value <= hi, or lo < value when open_low.
  void range(const std::string& path, double value, double lo, double hi, bool open_low = false) {
    if (open_low ? !(value > lo) : !(value >= lo)) {
      fail(path, str(value) + " must be " + (open_low ? "greater than " : "at least ") + str(lo));
    } else if (!(value <= hi)) {
      fail(path, str(value) + " must be at most " + str(hi));
    }
  }
  void positive(const std::string& path, double value, double hi) {
    range(path, value, 0.0, hi, true);
  }
  void fileExists(const std::string& path, const std::string& file) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) fail(path, "no such file: " + file);
  }

 private:
  const ConfigOrigins& origins_;
  std::vector<std::string>& problems_;
};

// The daq section's checks, shared by zerocald and `zerocal psd` (loadDaqSection).
void checkDaq(const psd::PsdConfig& d, Checker& check) {
  // An empty map_file is refused by the hardware backend when it starts, not here: the
  // compiled-in defaults stay a valid configuration for the simulated cell.
  if (!d.map_file.empty()) check.fileExists("daq.map_file", d.map_file);

  const std::pair<const char*, const usb1408fs::Channel*> channels[] = {
      {"x", &d.channels.x}, {"y", &d.channels.y}, {"sum", &d.channels.sum}};
  bool channels_valid = true;
  for (const auto& [name, channel] : channels) {
    const int highest = channel->mode == usb1408fs::InputMode::kDifferential ? 3 : 7;
    check.range(std::string("daq.channels.") + name + ".number", channel->number, 0, highest);
    channels_valid = channels_valid && channel->number >= 0 && channel->number <= highest;
  }
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = i + 1; j < 3; ++j) {
      const bool shared = usb1408fs::sharesTerminal(*channels[i].second, *channels[j].second);
      if (shared)
        check.fail(std::string("daq.channels.") + channels[j].first,
                   std::string("uses the same input as daq.channels.") + channels[i].first);
      channels_valid = channels_valid && !shared;
    }
  // The board scans consecutive inputs, lowest first (docs/usb1408fs.md): x, y, sum in that order.
  if (channels_valid &&
      (usb1408fs::wireChannel(d.channels.y) != usb1408fs::wireChannel(d.channels.x) + 1 ||
       usb1408fs::wireChannel(d.channels.sum) != usb1408fs::wireChannel(d.channels.y) + 1))
    check.fail("daq.channels",
               "x, y and sum must be consecutive inputs of one mode in that order (e.g. "
               "differential 0, 1, 2): the USB-1408FS scans a range of inputs");
  // The board converts at most 48 kS/s in all, shared by the three channels of a scan.
  check.positive("daq.scan_rate_hz", d.scan_rate_hz, 16000.0);
  check.range("daq.samples_per_reading", d.samples_per_reading, 1, 1000000);
  check.range("daq.sum_threshold_v", d.sum_threshold_v, 0.0, 20.0);
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
    problems.push_back(origin + ": unknown key '" + path + "'");
}

std::vector<std::string> validateDaemonConfig(const DaemonConfig& c, const ConfigOrigins& origins) {
  std::vector<std::string> problems;
  Checker check(origins, problems);

  const auto& b = c.backend;
  check.range("backend.sim_pace", b.sim_pace, 0.0, 10.0);
  check.range("backend.sim_gross_rate", b.sim_gross_rate, 0.0, 1.0);
  check.range("backend.sim_move_overhead_s", b.sim_move_overhead_s, 0.0, 60.0);
  if (b.kind == BackendKind::kSim) {
    if (!b.sim_world.empty() && b.sim_seed)
      check.fail("backend.sim_seed", "give backend.sim_world or backend.sim_seed, not both");
    if (!b.sim_world.empty()) check.fileExists("backend.sim_world", b.sim_world);
    if (b.sim_host.empty() != (b.sim_port == 0))
      check.fail(b.sim_host.empty() ? "backend.sim_port" : "backend.sim_host",
                 "an external zerocal-sim needs both backend.sim_host and backend.sim_port");
  }

  const auto& k = c.controller;
  const auto& l = k.irc5;
  if (k.robot != "builtin") check.fileExists("controller.robot", k.robot);
  if (b.kind == BackendKind::kHardware && l.host.empty())
    check.fail("controller.host", "must not be empty with backend.kind: hardware");
  if (l.port == 0) check.fail("controller.port", "must be 1..65535");
  check.positive("controller.connect_timeout_ms", l.connect_timeout.count(), 600000);
  check.positive("controller.request_timeout_ms", l.request_timeout.count(), 600000);
  check.range("controller.move_timeout_factor", l.move_timeout_factor, 1.0, 100.0);
  check.range("controller.move_timeout_margin_ms", l.move_timeout_margin.count(), 0, 600000);
  // 7000 mm/s and 1000 deg/s are above any IRC5 robot's maximum: beyond them a value is a typo.
  check.positive("controller.speed_tcp_mm_s", l.speed_tcp_mm_s, 7000.0);
  check.positive("controller.speed_ori_deg_s", l.speed_ori_deg_s, 1000.0);
  check.range("controller.limit_margin_deg", l.limit_margin_deg, 0.0, 30.0);
  // A calibration never needs one move larger than this; a larger step is a typing error.
  check.positive("controller.max_step_deg", k.max_step_deg, 45.0);
  check.range("controller.reconnect_attempts", l.reconnect_attempts, 0, 1000);
  // The wait for a restart shows no progress: it must stay below the worker's 120 s stall limit.
  check.positive("controller.restart_timeout_ms", l.restart_timeout.count(), 110000);

  checkDaq(c.daq, check);

  const auto& s = c.servo;
  check.positive("servo.tolerance_um", s.tolerance_um, 1000.0);
  // A servo step moves the spot a few mm; 5 deg moves it by tens of mm at 1 m.
  check.positive("servo.max_step_deg", s.max_step_deg, 5.0);
  if (s.max_step_deg > k.max_step_deg)
    check.fail("servo.max_step_deg", str(s.max_step_deg) + " exceeds controller.max_step_deg (" +
                                         str(k.max_step_deg) + ")");
  check.range("servo.max_iterations", s.max_iterations, 1, 100000);
  check.positive("servo.timeout_s", s.timeout_s, 3600.0);
  check.range("servo.settle_s", s.settle_s, 0.0, 60.0);
  check.positive("servo.search_radius_mm", s.search_radius_mm, 100.0);
  check.positive("servo.search_step_mm", s.search_step_mm, 100.0);
  if (s.search_step_mm > s.search_radius_mm)
    check.fail("servo.search_step_mm", str(s.search_step_mm) + " exceeds servo.search_radius_mm (" +
                                           str(s.search_radius_mm) + ")");
  check.positive("servo.search_time_s", s.search_time_s, 3600.0);
  check.range("servo.sweep_speed_mm_s", s.sweep_speed_mm_s, 0.0, 1000.0);
  if (s.sweep_speed_mm_s > l.speed_tcp_mm_s)
    check.fail("servo.sweep_speed_mm_s", str(s.sweep_speed_mm_s) +
                                             " exceeds controller.speed_tcp_mm_s (" +
                                             str(l.speed_tcp_mm_s) + ")");
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
  // Beyond a degree the offsets would be mastering errors, not a calibration's business.
  check.positive("session.required_accuracy_deg", n.required_accuracy_deg, 1.0);
  check.range("session.model_length_mm", n.model_length_mm, 0.0, 10.0);
  check.range("session.model_angle_deg", n.model_angle_deg, 0.0, 1.0);
  check.range("session.model_sag_deg", n.model_sag_deg, 0.0, 1.0);
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
  if (!problems.empty()) throw ConfigError("zerocald configuration", std::move(problems));
  return config;
}

nlohmann::json configToJson(const DaemonConfig& config) {
  DaemonConfig copy = config;
  Json out = Json::object();
  for (const auto& field : schema(copy)) {
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

psd::PsdConfig loadDaqSection(const std::string& path) {
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
          path, {"the psd: section of earlier versions is now the daq: section of zerocald's "
                 "configuration (docs/configuration.md): samples is samples_per_reading, rate_hz "
                 "scan_rate_hz, a channel's input its number, range_v: 5 range: 5V; "
                 "sum_off_threshold_v is 0.8 x sum_threshold_v, and the map is named by map_file"});
    throw ConfigError(path, {"the file must hold a 'daq:' section at its top level"});
  }
  DaemonConfig config;
  ConfigOrigins origins;
  const auto fields = schema(config);
  const std::string base_dir = fs::absolute(path).parent_path().string();
  Layer{fields, path, base_dir, origins, problems}.walk(root["daq"], "daq");
  Checker check(origins, problems);
  checkDaq(config.daq, check);
  if (!problems.empty()) throw ConfigError(path, std::move(problems));
  return config.daq;
}

std::string logLevelName(LogLevel level) {
  for (const auto& [name, value] : kLevels)
    if (value == level) return name;
  return "?";
}

}  // namespace zerocal
