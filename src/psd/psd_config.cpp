#include "zerocal/psd/psd_config.h"

#include <yaml-cpp/yaml.h>

#include <array>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <stdexcept>

#include "zerocal/error.h"

namespace zerocal::psd {
namespace {

using usb1408fs::Channel;
using usb1408fs::InputMode;
using usb1408fs::Range;

// The board converts at most 48 kS/s summed over the channels of a scan.
constexpr double kMaxAggregateRate = 48000.0;

struct RangeName {
  double volts;
  Range range;
};
constexpr std::array<RangeName, 8> kRanges{{{20, Range::kBip20V},
                                            {10, Range::kBip10V},
                                            {5, Range::kBip5V},
                                            {4, Range::kBip4V},
                                            {2.5, Range::kBip2_5V},
                                            {2, Range::kBip2V},
                                            {1.25, Range::kBip1_25V},
                                            {1, Range::kBip1V}}};

std::string joinKeys(const std::set<std::string>& keys) {
  std::string out;
  for (const auto& k : keys) out += (out.empty() ? "" : ", ") + k;
  return out;
}

// Reports keys a typo would produce, since yaml-cpp would otherwise ignore them silently.
void checkKeys(const YAML::Node& node, const std::set<std::string>& known, const std::string& where,
               std::vector<std::string>& problems) {
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (!known.count(key)) {
      problems.push_back(where + ": unknown key '" + key + "' (known: " + joinKeys(known) + ")");
    }
  }
}

template <typename T>
bool read(const YAML::Node& node, const std::string& where, T& out,
          std::vector<std::string>& problems, const char* what) {
  try {
    out = node.as<T>();
    return true;
  } catch (const YAML::Exception&) {
    problems.push_back(where + ": must be " + what);
    return false;
  }
}

std::vector<double> readNumbers(const YAML::Node& node, const std::string& where,
                                std::vector<std::string>& problems) {
  std::vector<double> out;
  if (!node.IsSequence()) {
    problems.push_back(where + ": must be a list of numbers");
    return out;
  }
  for (std::size_t i = 0; i < node.size(); ++i) {
    double value = 0;
    if (!read(node[i], where + "[" + std::to_string(i) + "]", value, problems, "a number")) {
      continue;
    }
    if (!std::isfinite(value))
      problems.push_back(where + "[" + std::to_string(i) + "]: not finite");
    out.push_back(value);
  }
  return out;
}

void parseChannel(const YAML::Node& node, const std::string& where, Channel& channel,
                  std::vector<std::string>& problems) {
  if (!node.IsMap()) {
    problems.push_back(where + ": must be a map {mode, input, range_v}");
    return;
  }
  checkKeys(node, {"mode", "input", "range_v"}, where, problems);
  if (node["mode"]) {
    std::string mode;
    if (read(node["mode"], where + ".mode", mode, problems, "differential or single_ended")) {
      if (mode == "differential") {
        channel.mode = InputMode::kDifferential;
      } else if (mode == "single_ended") {
        channel.mode = InputMode::kSingleEnded;
        channel.range = Range::kBip10V;  // the only single-ended range
      } else {
        problems.push_back(where + ".mode: '" + mode +
                           "' is neither differential nor single_ended");
      }
    }
  }
  if (node["input"]) read(node["input"], where + ".input", channel.number, problems, "an integer");
  if (node["range_v"]) {
    double volts = 0;
    if (read(node["range_v"], where + ".range_v", volts, problems, "a number")) {
      bool found = false;
      for (const auto& r : kRanges) {
        if (r.volts == volts) {
          channel.range = r.range;
          found = true;
        }
      }
      if (!found) {
        problems.push_back(where + ".range_v: " + node["range_v"].as<std::string>() +
                           " is not a range of the board (20, 10, 5, 4, 2.5, 2, 1.25, 1 for +-V)");
      } else if (channel.mode == InputMode::kSingleEnded && volts != 10) {
        problems.push_back(where + ".range_v: single-ended inputs are +-10 V only");
      }
    }
  }
}

std::string channelProblem(const Channel& c, const std::string& name) {
  const bool se = c.mode == InputMode::kSingleEnded;
  const int max = se ? 7 : 3;
  if (c.number < 0 || c.number > max) {
    return "channels." + name + ".input: " + std::to_string(c.number) + " is outside 0.." +
           std::to_string(max) + " for a " + (se ? "single-ended" : "differential") + " input";
  }
  return {};
}

std::string dirOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

std::string resolve(const std::string& base_dir, const std::string& file) {
  if (file.empty() || file.front() == '/' || base_dir.empty()) return file;
  return base_dir + "/" + file;
}

YAML::Node loadYamlFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, {"cannot open the file"});
  std::stringstream text;
  text << in.rdbuf();
  try {
    return YAML::Load(text.str());
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, {std::string("not valid YAML: ") + e.what()});
  }
}

PsdConfig parseSection(const YAML::Node& section, const std::string& origin,
                       const std::string& base_dir);

}  // namespace

std::vector<std::string> PsdConfig::problems() const {
  std::vector<std::string> out;
  const std::pair<const Channel*, const char*> named[3] = {
      {&channels.x, "x"}, {&channels.y, "y"}, {&channels.sum, "sum"}};
  bool numbers_ok = true;
  for (const auto& [channel, name] : named) {
    const std::string p = channelProblem(*channel, name);
    if (!p.empty()) {
      out.push_back(p);
      numbers_ok = false;
    }
  }
  if (numbers_ok) {
    for (int a = 0; a < 3; ++a) {
      for (int b = a + 1; b < 3; ++b) {
        if (usb1408fs::sharesTerminal(*named[a].first, *named[b].first)) {
          out.push_back(std::string("channels.") + named[a].second + " and channels." +
                        named[b].second + " use the same input terminals");
        }
      }
    }
  }
  if (samples < 2) {
    out.push_back("samples: " + std::to_string(samples) +
                  " per reading; at least 2 are needed for a standard error");
  } else if (samples > 1000000) {
    out.push_back("samples: " + std::to_string(samples) + " is more than 1000000");
  }
  if (!(rate_hz > 0) || !std::isfinite(rate_hz)) {
    out.push_back("rate_hz: must be positive");
  } else if (rate_hz * 3 > kMaxAggregateRate) {
    std::ostringstream m;
    m << "rate_hz: " << rate_hz << " scans/s of 3 channels is " << rate_hz * 3
      << " S/s; the board converts at most 48000 S/s (rate_hz <= 16000)";
    out.push_back(m.str());
  }
  const double sum_full_scale = usb1408fs::fullScaleVolts(channels.sum);
  if (!(sum_threshold_v > 0) || !(sum_threshold_v < sum_full_scale)) {
    std::ostringstream m;
    m << "sum_threshold_v: " << sum_threshold_v << " must be above 0 and below the SUM range (+-"
      << sum_full_scale << " V)";
    out.push_back(m.str());
  }
  if (!(sum_off_threshold_v >= 0) || !(sum_off_threshold_v <= sum_threshold_v)) {
    std::ostringstream m;
    m << "sum_off_threshold_v: " << sum_off_threshold_v
      << " must be between 0 and sum_threshold_v (" << sum_threshold_v << ")";
    out.push_back(m.str());
  }
  return out;
}

void PsdConfig::validate(const std::string& origin) const {
  auto p = problems();
  if (!p.empty()) throw ConfigError(origin, std::move(p));
}

PsdConfig parsePsdConfig(const YAML::Node& section, const std::string& origin,
                         const std::string& base_dir) {
  try {
    return parseSection(section, origin, base_dir);
  } catch (const YAML::Exception& e) {
    // Odd shapes (a list as a key, an alias to nothing) that the checks above did not foresee.
    throw ConfigError(origin, {std::string("psd: cannot be read: ") + e.what()});
  }
}

namespace {
PsdConfig parseSection(const YAML::Node& section, const std::string& origin,
                       const std::string& base_dir) {
  PsdConfig config;
  std::vector<std::string> problems;
  if (!section.IsMap()) throw ConfigError(origin, {"psd: must be a map"});
  checkKeys(section,
            {"serial", "channels", "samples", "rate_hz", "sum_threshold_v", "sum_off_threshold_v",
             "map_file", "map"},
            "psd", problems);
  if (section["serial"]) read(section["serial"], "serial", config.serial, problems, "a string");
  if (const YAML::Node channels = section["channels"]) {
    if (!channels.IsMap()) {
      problems.push_back("channels: must be a map with x, y and sum");
    } else {
      checkKeys(channels, {"x", "y", "sum"}, "channels", problems);
      if (channels["x"]) parseChannel(channels["x"], "channels.x", config.channels.x, problems);
      if (channels["y"]) parseChannel(channels["y"], "channels.y", config.channels.y, problems);
      if (channels["sum"]) {
        parseChannel(channels["sum"], "channels.sum", config.channels.sum, problems);
      }
    }
  }
  if (section["samples"]) {
    long long samples = 0;
    if (read(section["samples"], "samples", samples, problems, "a whole number")) {
      if (samples < 0) {
        problems.push_back("samples: must not be negative");
      } else {
        config.samples = static_cast<std::size_t>(samples);
      }
    }
  }
  if (section["rate_hz"]) read(section["rate_hz"], "rate_hz", config.rate_hz, problems, "a number");
  if (section["sum_threshold_v"]) {
    read(section["sum_threshold_v"], "sum_threshold_v", config.sum_threshold_v, problems,
         "a number");
  }
  const bool off_given = static_cast<bool>(section["sum_off_threshold_v"]);
  if (off_given) {
    read(section["sum_off_threshold_v"], "sum_off_threshold_v", config.sum_off_threshold_v,
         problems, "a number");
  } else {
    // Keep the hysteresis proportional when only the threshold is changed.
    config.sum_off_threshold_v = 0.8 * config.sum_threshold_v;
  }
  if (section["map_file"] && section["map"]) {
    problems.push_back("map_file and map: give one of them, not both");
  } else if (section["map_file"]) {
    if (read(section["map_file"], "map_file", config.map_file, problems, "a file name")) {
      try {
        config.map = loadPsdMap(resolve(base_dir, config.map_file));
      } catch (const ConfigError& e) {
        for (const auto& p : e.problems())
          problems.push_back("map_file " + config.map_file + ": " + p);
      }
    }
  } else if (section["map"]) {
    config.map = psdMapFromYaml(section["map"], "map", problems);
  }
  for (auto& p : config.problems()) problems.push_back(std::move(p));
  if (!problems.empty()) throw ConfigError(origin, std::move(problems));
  return config;
}
}  // namespace

PsdConfig loadPsdConfig(const std::string& path) {
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap() || !root["psd"]) {
    throw ConfigError(path, {"the file must hold a 'psd:' section at its top level"});
  }
  return parsePsdConfig(root["psd"], path, dirOf(path));
}

std::string psdMapToYaml(const PsdMap& map, const std::string& comment) {
  std::ostringstream out;
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  const auto zone = map.zone();
  // The zone and threshold are stage positions and volts: 12 digits print 0.6 as 0.6.
  out << std::setprecision(12) << "psd_map:\n  degree: " << map.degree() << "\n  zone_mm: {u: ["
      << zone[0] << ", " << zone[1] << "], v: [" << zone[2] << ", " << zone[3]
      << "]}\n  min_sum_v: " << map.minSumV() << "\n";
  // 17 significant digits: the coefficients of a degree-7 fit cancel each other, so a rounded
  // copy would not reproduce the fitted positions to the micrometre.
  out << std::setprecision(17);
  for (const auto& [name, coeff] :
       {std::pair{"u", &map.uCoefficients()}, std::pair{"v", &map.vCoefficients()}}) {
    out << "  " << name << ": [";
    for (std::size_t i = 0; i < coeff->size(); ++i) out << (i ? ", " : "") << (*coeff)[i];
    out << "]\n";
  }
  return out.str();
}

std::optional<PsdMap> psdMapFromYaml(const YAML::Node& node, const std::string& where,
                                     std::vector<std::string>& problems) {
  const std::size_t before = problems.size();
  if (!node.IsMap()) {
    problems.push_back(where + ": must be a map {degree, zone_mm, min_sum_v, u, v}");
    return std::nullopt;
  }
  checkKeys(node, {"degree", "zone_mm", "min_sum_v", "u", "v"}, where, problems);
  int degree = 0;
  double min_sum_v = 0.5;
  std::array<double, 4> zone{};
  std::vector<double> u, v;
  for (const char* key : {"degree", "zone_mm", "u", "v"}) {
    if (!node[key]) problems.push_back(where + ": missing '" + key + "'");
  }
  if (node["degree"] && read(node["degree"], where + ".degree", degree, problems, "an integer") &&
      (degree < 1 || degree > 12)) {
    problems.push_back(where + ".degree: " + std::to_string(degree) + " is outside 1..12");
  }
  if (node["min_sum_v"]) {
    read(node["min_sum_v"], where + ".min_sum_v", min_sum_v, problems, "a number");
  }
  if (const YAML::Node z = node["zone_mm"]) {
    if (!z.IsMap() || !z["u"] || !z["v"]) {
      problems.push_back(where + ".zone_mm: must be {u: [min, max], v: [min, max]}");
    } else {
      for (int axis = 0; axis < 2; ++axis) {
        const std::string name = axis == 0 ? "u" : "v";
        const auto pair = readNumbers(z[name], where + ".zone_mm." + name, problems);
        if (pair.size() != 2) {
          problems.push_back(where + ".zone_mm." + name + ": must be [min, max]");
        } else if (!(pair[0] < pair[1])) {
          problems.push_back(where + ".zone_mm." + name + ": min must be below max");
        } else {
          zone[2 * axis] = pair[0];
          zone[2 * axis + 1] = pair[1];
        }
      }
    }
  }
  if (node["u"]) u = readNumbers(node["u"], where + ".u", problems);
  if (node["v"]) v = readNumbers(node["v"], where + ".v", problems);
  const std::size_t m = PsdMap::termCount(degree);
  if (degree >= 1 && degree <= 12) {
    if (node["u"] && u.size() != m) {
      problems.push_back(where + ".u: " + std::to_string(u.size()) + " coefficients; degree " +
                         std::to_string(degree) + " needs " + std::to_string(m));
    }
    if (node["v"] && v.size() != m) {
      problems.push_back(where + ".v: " + std::to_string(v.size()) + " coefficients; degree " +
                         std::to_string(degree) + " needs " + std::to_string(m));
    }
  }
  if (problems.size() != before) return std::nullopt;
  try {
    return PsdMap::fromParts(degree, std::move(u), std::move(v), zone, min_sum_v);
  } catch (const std::invalid_argument& e) {
    problems.push_back(where + ": " + e.what());
    return std::nullopt;
  }
}

PsdMap loadPsdMap(const std::string& path) {
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap() || !root["psd_map"]) {
    throw ConfigError(path, {"the file must hold a 'psd_map:' section (zerocal psd-map --out)"});
  }
  std::vector<std::string> problems;
  std::optional<PsdMap> map;
  try {
    map = psdMapFromYaml(root["psd_map"], "psd_map", problems);
  } catch (const YAML::Exception& e) {
    problems.push_back(std::string("psd_map: cannot be read: ") + e.what());
  }
  if (!map) throw ConfigError(path, std::move(problems));
  return *map;
}

}  // namespace zerocal::psd
