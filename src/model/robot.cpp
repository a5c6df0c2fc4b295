#include "zerocal/model/robot.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <tuple>

#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {

ConfigError::ConfigError(const std::string& origin, std::vector<std::string> problems)
    : Error([&] {
        std::string text = origin + ": " + std::to_string(problems.size()) + " problem" +
                           (problems.size() == 1 ? "" : "s");
        for (const auto& p : problems) text += "\n  - " + p;
        return text;
      }()),
      problems_(std::move(problems)) {}

bool Robot::withinLimits(const Joints& q_deg, double margin_deg) const {
  return limitViolation(q_deg, margin_deg).empty();
}

std::string Robot::limitViolation(const Joints& q_deg, double margin_deg) const {
  for (int i = 0; i < kJointCount; ++i) {
    const double lo = limits[i].lower_deg + margin_deg, hi = limits[i].upper_deg - margin_deg;
    if (!(q_deg[i] >= lo && q_deg[i] <= hi)) {
      std::ostringstream s;
      s << "joint " << i + 1 << " = " << q_deg[i] << " deg is outside [" << lo << ", " << hi
        << "] deg";
      if (margin_deg > 0) s << " (limits less a " << margin_deg << " deg margin)";
      return s.str();
    }
  }
  return {};
}

namespace {

// Reads one required finite number, recording a problem instead of throwing.
double number(const YAML::Node& map, const std::string& key, const std::string& where,
              std::vector<std::string>& problems) {
  const YAML::Node node = map[key];
  if (!node) {
    problems.push_back(where + ": missing '" + key + "'");
    return 0;
  }
  try {
    const double v = node.as<double>();
    if (!std::isfinite(v)) problems.push_back(where + ": '" + key + "' is not finite");
    return v;
  } catch (const YAML::Exception&) {
    problems.push_back(where + ": '" + key + "' is not a number");
    return 0;
  }
}

constexpr double kMaxJointTravelDeg = 720;  // two turns either way
constexpr double kMaxLinkMm = 10000;
constexpr double kMinJointSpeedDegS = 0.1, kMaxJointSpeedDegS = 2000;

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

Robot parseRobot(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, {std::string("not valid YAML: ") + e.what()});
  }
  std::vector<std::string> problems;
  Robot robot;
  if (!root.IsMap()) throw ConfigError(origin, {"the file must be a YAML map"});
  if (!root["name"] || !root["name"].IsScalar())
    problems.push_back("missing 'name'");
  else
    robot.name = root["name"].as<std::string>();

  const YAML::Node joints = root["joints"];
  if (!joints || !joints.IsSequence()) {
    problems.push_back("missing 'joints' (a list of 6 joints)");
  } else if (joints.size() != kJointCount) {
    problems.push_back("'joints' has " + std::to_string(joints.size()) +
                       " entries; a 6R arm needs exactly 6");
  } else {
    for (int i = 0; i < kJointCount; ++i) {
      const std::string where = "joint " + std::to_string(i + 1);
      const YAML::Node j = joints[i];
      if (!j.IsMap()) {
        problems.push_back(where + ": must be a map");
        continue;
      }
      DhRow& row = robot.dh[i];
      row.a_mm = number(j, "a_mm", where, problems);
      row.alpha_rad = number(j, "alpha_deg", where, problems) * kDegToRad;
      row.d_mm = number(j, "d_mm", where, problems);
      row.theta_offset_rad = number(j, "theta_offset_deg", where, problems) * kDegToRad;
      JointLimit& lim = robot.limits[i];
      lim.lower_deg = number(j, "lower_deg", where, problems);
      lim.upper_deg = number(j, "upper_deg", where, problems);
      if (j["lower_deg"] && j["upper_deg"] && !(lim.lower_deg < lim.upper_deg))
        problems.push_back(where + ": lower_deg must be below upper_deg");
      // Beyond these no industrial arm goes: such a value is a typing error that would make
      // every limit check (and every move deadline) meaningless.
      for (const auto& [key, value, bound] :
           {std::tuple<const char*, double, double>{"lower_deg", lim.lower_deg, kMaxJointTravelDeg},
            {"upper_deg", lim.upper_deg, kMaxJointTravelDeg},
            {"a_mm", row.a_mm, kMaxLinkMm},
            {"d_mm", row.d_mm, kMaxLinkMm}})
        if (j[key] && std::isfinite(value) && !(std::abs(value) <= bound))
          problems.push_back(where + ": " + key + " must lie within +-" + fmt(bound));
      robot.max_speed_deg_s[i] = number(j, "max_speed_deg_s", where, problems);
      if (j["max_speed_deg_s"] && !(robot.max_speed_deg_s[i] >= kMinJointSpeedDegS &&
                                    robot.max_speed_deg_s[i] <= kMaxJointSpeedDegS))
        problems.push_back(where + ": max_speed_deg_s must lie within " + fmt(kMinJointSpeedDegS) +
                           ".." + fmt(kMaxJointSpeedDegS));
      if (j["transmission"]) {
        // Written with its sign ("+120", "-80"): a bare magnitude is how signs get lost.
        const std::string text = j["transmission"].IsScalar() ? j["transmission"].Scalar() : "";
        robot.transmission[i] = number(j, "transmission", where, problems);
        if (text.empty() || (text[0] != '+' && text[0] != '-'))
          problems.push_back(where + ": 'transmission' must be written with its sign (+ or -)");
        else if (!(std::abs(robot.transmission[i]) >= 1.0))
          problems.push_back(where + ": 'transmission' must be at least 1 in magnitude");
      }
      for (const auto& kv : j) {
        static const char* known[] = {
            "a_mm",      "alpha_deg",       "d_mm",        "theta_offset_deg", "lower_deg",
            "upper_deg", "max_speed_deg_s", "transmission"};
        const auto key = kv.first.as<std::string>();
        bool ok = false;
        for (const char* k : known) ok = ok || key == k;
        if (!ok) problems.push_back(where + ": unknown key '" + key + "'");
      }
    }
  }
  if (const YAML::Node confirmed = root["transmission_confirmed"]) {
    try {
      robot.transmission_confirmed = confirmed.as<bool>();
    } catch (const YAML::Exception&) {
      problems.push_back("'transmission_confirmed' must be true or false");
    }
  }
  for (const auto& kv : root) {
    const auto key = kv.first.as<std::string>();
    if (key != "name" && key != "joints" && key != "description" && key != "transmission_confirmed")
      problems.push_back("unknown key '" + key + "'");
  }
  if (!problems.empty()) throw ConfigError(origin, std::move(problems));
  return robot;
}

Robot loadRobot(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, {"cannot open the robot file"});
  std::stringstream text;
  text << in.rdbuf();
  return parseRobot(text.str(), path);
}

Frame<double> flangePoseDeg(const Robot& robot, const Joints& q_deg, const Joints& delta_deg) {
  double rad[kJointCount];
  for (int i = 0; i < kJointCount; ++i) rad[i] = (q_deg[i] + delta_deg[i]) * kDegToRad;
  return flangePose(robot, rad);
}

}  // namespace zerocal
