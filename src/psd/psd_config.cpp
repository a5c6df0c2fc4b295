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

std::string readYamlFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, {"cannot open the file"});
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

std::string psdMapToYaml(const PsdMap& map, const std::string& comment) {
  std::ostringstream out;
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  const auto zone = map.zone();
  // The zone and threshold are stage positions and volts: 12 digits print 0.6 as 0.6. The
  // coefficients take 17: those of a degree-7 fit cancel each other, so a rounded copy would not
  // reproduce the fitted positions to the micrometre.
  const auto digits = [](double v, int precision) {
    std::ostringstream o;
    o << std::setprecision(precision) << v;
    return o.str();
  };
  YAML::Emitter y;
  y << YAML::BeginMap << YAML::Key << "psd_map" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "degree" << YAML::Value << map.degree();
  y << YAML::Key << "zone_mm" << YAML::Value << YAML::Flow << YAML::BeginMap;
  y << YAML::Key << "u" << YAML::Value << YAML::Flow << YAML::BeginSeq << digits(zone[0], 12)
    << digits(zone[1], 12) << YAML::EndSeq;
  y << YAML::Key << "v" << YAML::Value << YAML::Flow << YAML::BeginSeq << digits(zone[2], 12)
    << digits(zone[3], 12) << YAML::EndSeq;
  y << YAML::EndMap;
  y << YAML::Key << "min_sum_v" << YAML::Value << digits(map.minSumV(), 12);
  for (const auto& [name, coeff] :
       {std::pair{"u", &map.uCoefficients()}, std::pair{"v", &map.vCoefficients()}}) {
    y << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const double c : *coeff) y << digits(c, 17);
    y << YAML::EndSeq;
  }
  y << YAML::EndMap << YAML::EndMap;
  out << y.c_str() << "\n";
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
  if (degree >= 1 && degree <= 12) {
    const std::size_t m = PsdMap::termCount(degree);
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

PsdMap loadPsdMap(const std::string& path) { return parsePsdMap(readYamlFile(path), path); }

PsdMap parsePsdMap(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, {std::string("not valid YAML: ") + e.what()});
  }
  if (!root.IsMap() || !root["psd_map"]) {
    throw ConfigError(origin, {"the file must hold a 'psd_map:' section (zerocal psd-map --out)"});
  }
  std::vector<std::string> problems;
  std::optional<PsdMap> map;
  try {
    map = psdMapFromYaml(root["psd_map"], "psd_map", problems);
  } catch (const YAML::Exception& e) {
    problems.push_back(std::string("psd_map: cannot be read: ") + e.what());
  }
  if (!map) throw ConfigError(origin, std::move(problems));
  return *map;
}

}  // namespace zerocal::psd
