#include "zerocal/model/robot.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
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

// The problems of one file, each as "file:line: what" (the line of the node it is about), so
// that an editor jumps to it; the `what` names the key.
class Problems {
 public:
  explicit Problems(std::string origin) : origin_(std::move(origin)) {}
  void add(const YAML::Node& near, const std::string& what) {
    const YAML::Mark mark = near.Mark();
    list_.push_back(origin_ + (mark.is_null() ? "" : ":" + std::to_string(mark.line + 1)) + ": " +
                    what);
  }
  void add(const YAML::Mark& mark, const std::string& what) {
    list_.push_back(origin_ + (mark.is_null() ? "" : ":" + std::to_string(mark.line + 1)) + ": " +
                    what);
  }
  bool empty() const { return list_.empty(); }
  std::vector<std::string> take() { return std::move(list_); }

 private:
  std::string origin_;
  std::vector<std::string> list_;
};

// A map's key as written; a key that is a list or a map is no key of a robot file.
std::string keyOf(const YAML::Node& key) {
  return key.IsScalar() ? key.Scalar() : std::string("(a key that is not a word)");
}

// Reads one required finite number, recording a problem instead of throwing.
double number(const YAML::Node& map, const std::string& key, const std::string& where,
              Problems& problems) {
  const YAML::Node node = map[key];
  if (!node) {
    problems.add(map, where + ": missing '" + key + "'");
    return 0;
  }
  try {
    const double v = node.as<double>();
    if (!std::isfinite(v)) {
      problems.add(node, where + ": '" + key + "' is not finite");
      return 0;
    }
    return v;
  } catch (const YAML::Exception&) {
    problems.add(node, where + ": '" + key + "' is not a number");
    return 0;
  }
}

constexpr double kMaxLinkMm = 10000;
// A DH twist or joint offset is an angle: beyond a full turn it is a typing error.
constexpr double kMaxDhAngleDeg = 360;
constexpr double kMinJointSpeedDegS = 0.1, kMaxJointSpeedDegS = 2000;
// A transmission is a gear ratio: at least 1 (a motor is never geared up), and no arm's reaches
// 1000: industrial arms' are of the order of tens to a few hundred (the shipped IRB 1600 file's
// placeholders are 50..120; ABB publishes no values).
constexpr double kMinTransmission = 1, kMaxTransmission = 1000;
// An identified link error or compliance beyond these is not a calibration of this arm.
constexpr double kMaxLinkErrorMm = 10, kMaxLinkErrorDeg = 1;
constexpr double kMaxComplianceDegPerKnm = 10;
constexpr double kMaxMassKg = 10000;

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The optional `gravity` section (the lumped masses) and the identified compliance of a
// calibrated model, which needs them.
void parseGravity(const YAML::Node& root, Robot& robot, Problems& problems) {
  if (const YAML::Node g = root["gravity"]) {
    if (!g.IsMap()) {
      problems.add(g, "gravity: must be a map with 'masses' (and 'inferred')");
    } else {
      for (const auto& kv : g) {
        const auto key = keyOf(kv.first);
        if (key != "masses" && key != "inferred")
          problems.add(kv.first, "gravity: unknown key '" + key + "'");
      }
      if (const YAML::Node inferred = g["inferred"]) {
        try {
          robot.masses_inferred = inferred.as<bool>();
        } catch (const YAML::Exception&) {
          problems.add(inferred, "gravity: 'inferred' must be true or false");
        }
      }
      const YAML::Node masses = g["masses"];
      if (!masses || !masses.IsSequence() || masses.size() == 0) {
        problems.add(masses ? masses : g, "gravity: 'masses' must be a list of {link, kg, at_mm}");
      } else {
        for (std::size_t k = 0; k < masses.size(); ++k) {
          const std::string where = "gravity mass " + std::to_string(k + 1);
          const YAML::Node m = masses[k];
          if (!m.IsMap()) {
            problems.add(m, where + ": must be a map");
            continue;
          }
          LumpedMass mass;
          const double link = number(m, "link", where, problems);
          // Compared as a double first: a link of 1e300 has no int to be cast to.
          const bool whole = link == std::floor(link) && link >= 2 && link <= kJointCount;
          mass.link = whole ? static_cast<int>(link) : 0;
          if (m["link"] && !whole)
            problems.add(m["link"], where +
                                        ": 'link' must be a whole number from 2 to 6 (the DH "
                                        "frame the mass rides in; masses on link 1 load neither "
                                        "joint 2 nor 3)");
          mass.kg = number(m, "kg", where, problems);
          if (m["kg"] && !(mass.kg > 0 && mass.kg <= kMaxMassKg))
            problems.add(m["kg"], where + ": 'kg' must lie within 0.." + fmt(kMaxMassKg) +
                                      " (exclusive of 0)");
          const YAML::Node at = m["at_mm"];
          if (!at || !at.IsSequence() || at.size() != 3) {
            problems.add(at ? at : m, where +
                                          ": 'at_mm' must be a list of 3 numbers (mm, in the "
                                          "link's DH frame)");
          } else {
            for (int a = 0; a < 3; ++a) {
              try {
                mass.at_mm[a] = at[a].as<double>();
                if (!(std::abs(mass.at_mm[a]) <= kMaxLinkMm)) throw YAML::Exception({}, "");
              } catch (const YAML::Exception&) {
                problems.add(at[a], where + ": at_mm[" + std::to_string(a) +
                                        "] must be a number within +-" + fmt(kMaxLinkMm));
              }
            }
          }
          for (const auto& kv : m) {
            const auto key = keyOf(kv.first);
            if (key != "link" && key != "kg" && key != "at_mm")
              problems.add(kv.first, where + ": unknown key '" + key + "'");
          }
          robot.masses.push_back(mass);
        }
      }
    }
  }
  if (const YAML::Node c = root["compliance_deg_per_knm"]) {
    if (!c.IsSequence() || c.size() != kComplianceCount) {
      problems.add(c, "compliance_deg_per_knm: must be a list of 2 numbers (joints 2 and 3)");
    } else {
      for (int k = 0; k < kComplianceCount; ++k) {
        try {
          robot.compliance_deg_per_knm[k] = c[k].as<double>();
          if (!(std::abs(robot.compliance_deg_per_knm[k]) <= kMaxComplianceDegPerKnm))
            throw YAML::Exception({}, "");
        } catch (const YAML::Exception&) {
          problems.add(c[k], "compliance_deg_per_knm[" + std::to_string(k) +
                                 "]: must be a number within +-" + fmt(kMaxComplianceDegPerKnm));
        }
      }
      if (!root["gravity"])
        problems.add(c,
                     "compliance_deg_per_knm needs the 'gravity' section: the compliance "
                     "multiplies the gravity torque of its masses");
    }
  }
}

// A link parameter (a1, d1, alpha1, a2, ...) in the file's unit, mm or deg, per internal unit
// (mm or rad): link_covariance is written in mm and deg, held in mm and rad.
double fileUnit(int k) { return k % 3 == 2 ? kDegToRad : 1.0; }

// The one-sigma tolerances a model may state: beyond these it is not a model of the arm.
constexpr double kMaxLengthToleranceMm = 10, kMaxAngleToleranceDeg = 1;

void parseTolerance(const YAML::Node& root, Robot& robot, Problems& problems) {
  const YAML::Node t = root["model_tolerance"];
  if (!t) {
    problems.add(root,
                 "missing 'model_tolerance': the one-sigma tolerances of this model's link "
                 "lengths (length_mm) and twists (angle_deg), which every solve counts "
                 "(docs/file-formats.md); 0 and 0 state a model taken as exact");
    return;
  }
  if (!t.IsMap()) {
    problems.add(t, "model_tolerance: must be a map with 'length_mm' and 'angle_deg'");
    return;
  }
  const std::string where = "model_tolerance";
  ModelTolerances& m = robot.tolerance;
  m.length_mm = number(t, "length_mm", where, problems);
  m.angle_deg = number(t, "angle_deg", where, problems);
  for (const auto& [key, value, bound] :
       {std::tuple<const char*, double, double>{"length_mm", m.length_mm, kMaxLengthToleranceMm},
        {"angle_deg", m.angle_deg, kMaxAngleToleranceDeg}})
    if (t[key] && !(value >= 0 && value <= bound))
      problems.add(t[key], where + ": '" + key + "' must lie within 0.." + fmt(bound));
  // Joints 2 and 3 in turn; one number is both joints' (a model that states no split).
  const auto readSag = [&](const char* key, SagTolerances& out) {
    const YAML::Node sag = t[key];
    if (!sag) return;
    try {
      const std::vector<double> given =
          sag.IsSequence() ? sag.as<std::vector<double>>() : std::vector<double>{sag.as<double>()};
      const bool within = std::all_of(given.begin(), given.end(), [](double v) {
        return v >= 0 && v <= kMaxAngleToleranceDeg;  // NaN too is refused
      });
      if (!within || (sag.IsSequence() && given.size() != kComplianceCount))
        throw YAML::Exception({}, "");
      out = sagTolerancesOf(given);
    } catch (const YAML::Exception&) {
      problems.add(sag, where + ": '" + key +
                            "' must be a number or a list of 2 numbers (joints 2 and 3), each "
                            "within 0.." +
                            fmt(kMaxAngleToleranceDeg));
    }
  };
  readSag("sag_deg", m.sag_deg);
  readSag("sag_mean_deg", m.sag_mean_deg);
  // A mean beyond its RMS would be a negative variance (a mean without an RMS is one).
  if (const YAML::Node mean = t["sag_mean_deg"])
    if (anyCounted(m.sag_mean_deg) &&
        !(m.sag_mean_deg[0] <= m.sag_deg[0] && m.sag_mean_deg[1] <= m.sag_deg[1]))
      problems.add(mean, where +
                             ": each 'sag_mean_deg' must lie within 0..its 'sag_deg' (a "
                             "sag's mean cannot exceed its RMS)");
  if (const YAML::Node c = t["link_covariance"]) {
    // A calibrated model's: rows and columns a1, d1, alpha1, a2, ... in mm and deg.
    const std::string shape = where + ": 'link_covariance' must be " +
                              std::to_string(kLinkParameterCount) + " rows of " +
                              std::to_string(kLinkParameterCount) +
                              " numbers (a, d in mm and alpha in deg of each joint)";
    if (!c.IsSequence() || c.size() != kLinkParameterCount) {
      problems.add(c, shape);
    } else {
      Eigen::MatrixXd cov(kLinkParameterCount, kLinkParameterCount);
      bool ok = true;
      for (int r = 0; r < kLinkParameterCount && ok; ++r) {
        if (!c[r].IsSequence() || c[r].size() != kLinkParameterCount) {
          problems.add(c[r], shape);
          ok = false;
          break;
        }
        for (int k = 0; k < kLinkParameterCount; ++k) {
          try {
            const double v = c[r][k].as<double>();
            if (!std::isfinite(v)) throw YAML::Exception({}, "");
            cov(r, k) = v * fileUnit(r) * fileUnit(k);
          } catch (const YAML::Exception&) {
            problems.add(c[r][k], where + ": link_covariance[" + std::to_string(r) + "][" +
                                      std::to_string(k) + "] is not a finite number");
            ok = false;
          }
        }
      }
      if (ok) {
        const double scale = cov.cwiseAbs().maxCoeff();
        const double min_eigen =
            Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (cov + cov.transpose()))
                .eigenvalues()
                .minCoeff();
        if (!((cov - cov.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale))
          problems.add(c, where + ": 'link_covariance' is not symmetric");
        else if (!(min_eigen >= -1e-9 * scale))
          problems.add(c, where +
                              ": 'link_covariance' is not a covariance (not positive "
                              "semi-definite)");
        else
          m.link_covariance = cov;
      }
    }
  }
  for (const auto& kv : t) {
    const auto key = keyOf(kv.first);
    if (key != "length_mm" && key != "angle_deg" && key != "sag_deg" && key != "sag_mean_deg" &&
        key != "link_covariance")
      problems.add(kv.first, where + ": unknown key '" + key + "'");
  }
}

void parseJoints(const YAML::Node& root, Robot& robot, Problems& problems) {
  const YAML::Node joints = root["joints"];
  if (!joints || !joints.IsSequence()) {
    problems.add(joints ? joints : root, "missing 'joints' (a list of 6 joints)");
    return;
  }
  if (joints.size() != kJointCount) {
    problems.add(joints, "'joints' has " + std::to_string(joints.size()) +
                             " entries; a 6R arm needs exactly 6");
    return;
  }
  for (int i = 0; i < kJointCount; ++i) {
    const std::string where = "joint " + std::to_string(i + 1);
    const YAML::Node j = joints[i];
    if (!j.IsMap()) {
      problems.add(j, where + ": must be a map");
      continue;
    }
    DhRow& row = robot.dh[i];
    row.a_mm = number(j, "a_mm", where, problems);
    const double alpha_deg = number(j, "alpha_deg", where, problems);
    row.alpha_rad = alpha_deg * kDegToRad;
    row.d_mm = number(j, "d_mm", where, problems);
    const double theta_offset_deg = number(j, "theta_offset_deg", where, problems);
    row.theta_offset_rad = theta_offset_deg * kDegToRad;
    JointLimit& lim = robot.limits[i];
    lim.lower_deg = number(j, "lower_deg", where, problems);
    lim.upper_deg = number(j, "upper_deg", where, problems);
    if (j["lower_deg"] && j["upper_deg"] && !(lim.lower_deg < lim.upper_deg))
      problems.add(j["lower_deg"], where + ": lower_deg must be below upper_deg");
    // Beyond these no industrial arm goes: such a value is a typing error that would make
    // every limit check (and every move deadline) meaningless.
    for (const auto& [key, value, bound] :
         {std::tuple<const char*, double, double>{"lower_deg", lim.lower_deg, kMaxJointTravelDeg},
          {"upper_deg", lim.upper_deg, kMaxJointTravelDeg},
          {"a_mm", row.a_mm, kMaxLinkMm},
          {"d_mm", row.d_mm, kMaxLinkMm},
          {"alpha_deg", alpha_deg, kMaxDhAngleDeg},
          {"theta_offset_deg", theta_offset_deg, kMaxDhAngleDeg}})
      if (j[key] && !(std::abs(value) <= bound))
        problems.add(j[key], where + ": " + key + " must lie within +-" + fmt(bound));
    robot.max_speed_deg_s[i] = number(j, "max_speed_deg_s", where, problems);
    if (j["max_speed_deg_s"] && !(robot.max_speed_deg_s[i] >= kMinJointSpeedDegS &&
                                  robot.max_speed_deg_s[i] <= kMaxJointSpeedDegS))
      problems.add(j["max_speed_deg_s"], where + ": max_speed_deg_s must lie within " +
                                             fmt(kMinJointSpeedDegS) + ".." +
                                             fmt(kMaxJointSpeedDegS));
    if (const YAML::Node t = j["transmission"]) {
      // Written with its sign ("+120", "-80"): a bare magnitude is how signs get lost.
      const std::string text = t.IsScalar() ? t.Scalar() : "";
      robot.transmission[i] = number(j, "transmission", where, problems);
      const double magnitude = std::abs(robot.transmission[i]);
      if (text.empty() || (text[0] != '+' && text[0] != '-'))
        problems.add(t, where + ": 'transmission' must be written with its sign (+ or -)");
      else if (!(magnitude >= kMinTransmission))
        problems.add(t, where + ": 'transmission' must be at least 1 in magnitude");
      else if (!(magnitude <= kMaxTransmission))
        problems.add(t, where + ": 'transmission' must be at most " + fmt(kMaxTransmission) +
                            " in magnitude (a gear ratio)");
    }
    // Identified errors of a calibrated model (zerocal solve --save-model): added to the row.
    auto& error = robot.identified_link_error[i];
    for (const auto& [key, index, bound] :
         {std::tuple<const char*, int, double>{"da_mm", 0, kMaxLinkErrorMm},
          {"dd_mm", 1, kMaxLinkErrorMm},
          {"dalpha_deg", 2, kMaxLinkErrorDeg}}) {
      if (!j[key]) continue;
      const double v = number(j, key, where, problems);
      if (!(std::abs(v) <= bound))
        problems.add(j[key], where + ": " + key + " must lie within +-" + fmt(bound) +
                                 " (an identified error, not a link length)");
      else
        error[index] = index == 2 ? v * kDegToRad : v;
    }
    row.a_mm += error[0];
    row.d_mm += error[1];
    row.alpha_rad += error[2];
    for (const auto& kv : j) {
      static const char* known[] = {"a_mm",
                                    "alpha_deg",
                                    "d_mm",
                                    "theta_offset_deg",
                                    "lower_deg",
                                    "upper_deg",
                                    "max_speed_deg_s",
                                    "transmission",
                                    "da_mm",
                                    "dd_mm",
                                    "dalpha_deg"};
      const auto key = keyOf(kv.first);
      bool ok = false;
      for (const char* k : known) ok = ok || key == k;
      if (!ok) problems.add(kv.first, where + ": unknown key '" + key + "'");
    }
  }
}

}  // namespace

Robot parseRobot(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin,
                      {origin + (e.mark.is_null() ? "" : ":" + std::to_string(e.mark.line + 1)) +
                       ": not valid YAML: " + e.msg});
  }
  if (!root.IsMap()) throw ConfigError(origin, {origin + ": the file must be a YAML map"});
  Problems problems(origin);
  Robot robot;
  try {
    if (!root["name"] || !root["name"].IsScalar())
      problems.add(root["name"] ? root["name"] : root, "missing 'name'");
    else
      robot.name = root["name"].Scalar();
    parseJoints(root, robot, problems);
    if (const YAML::Node confirmed = root["transmission_confirmed"]) {
      try {
        robot.transmission_confirmed = confirmed.as<bool>();
      } catch (const YAML::Exception&) {
        problems.add(confirmed, "'transmission_confirmed' must be true or false");
      }
    }
    parseGravity(root, robot, problems);
    parseTolerance(root, robot, problems);
    for (const auto& kv : root) {
      const auto key = keyOf(kv.first);
      if (key != "name" && key != "joints" && key != "description" &&
          key != "transmission_confirmed" && key != "gravity" && key != "compliance_deg_per_knm" &&
          key != "model_tolerance")
        problems.add(kv.first, "unknown key '" + key + "'");
    }
  } catch (const YAML::Exception& e) {
    // Each read above expects the shape it checked; whatever slips past is still the file's
    // fault, never a crash.
    problems.add(e.mark, "unexpected structure: " + e.msg);
  }
  if (!problems.empty()) throw ConfigError(origin, problems.take());
  return robot;
}

namespace {

std::string exact(double v) { return fmt::format(FMT_STRING("{:.17g}"), v); }

}  // namespace

std::string robotYaml(const Robot& robot, const std::string& comment) {
  std::ostringstream o;
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) o << "# " << line << "\n";
  // yaml-cpp's emitter quotes and escapes; each number is written exactly (17 digits), as text.
  YAML::Emitter y;
  y << YAML::BeginMap;
  y << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << robot.name;
  y << YAML::Key << "transmission_confirmed" << YAML::Value << robot.transmission_confirmed;
  y << YAML::Key << "joints" << YAML::Value << YAML::BeginSeq;
  for (int i = 0; i < kJointCount; ++i) {
    const DhRow& row = robot.dh[i];
    const auto& e = robot.identified_link_error[i];
    y << YAML::Flow << YAML::BeginMap;
    const auto put = [&y](const char* key, const std::string& value) {
      y << YAML::Key << key << YAML::Value << value;
    };
    put("a_mm", exact(row.a_mm - e[0]));
    put("alpha_deg", exact((row.alpha_rad - e[2]) * kRadToDeg));
    put("d_mm", exact(row.d_mm - e[1]));
    put("theta_offset_deg", exact(row.theta_offset_rad * kRadToDeg));
    put("lower_deg", exact(robot.limits[i].lower_deg));
    put("upper_deg", exact(robot.limits[i].upper_deg));
    put("max_speed_deg_s", exact(robot.max_speed_deg_s[i]));
    if (robot.transmission[i] != 0)
      put("transmission", (robot.transmission[i] > 0 ? "+" : "") + exact(robot.transmission[i]));
    if (e[0] != 0 || e[1] != 0 || e[2] != 0) {
      put("da_mm", exact(e[0]));
      put("dd_mm", exact(e[1]));
      put("dalpha_deg", exact(e[2] * kRadToDeg));
    }
    y << YAML::EndMap;
  }
  y << YAML::EndSeq;
  if (robot.hasGravityModel()) {
    y << YAML::Key << "gravity" << YAML::Value << YAML::BeginMap;
    y << YAML::Key << "inferred" << YAML::Value << robot.masses_inferred;
    y << YAML::Key << "masses" << YAML::Value << YAML::BeginSeq;
    for (const LumpedMass& m : robot.masses)
      y << YAML::Flow << YAML::BeginMap << YAML::Key << "link" << YAML::Value << m.link << YAML::Key
        << "kg" << YAML::Value << exact(m.kg) << YAML::Key << "at_mm" << YAML::Value << YAML::Flow
        << YAML::BeginSeq << exact(m.at_mm[0]) << exact(m.at_mm[1]) << exact(m.at_mm[2])
        << YAML::EndSeq << YAML::EndMap;
    y << YAML::EndSeq << YAML::EndMap;
  }
  if (robot.hasCompliance())
    y << YAML::Key << "compliance_deg_per_knm" << YAML::Value << YAML::Flow << YAML::BeginSeq
      << exact(robot.compliance_deg_per_knm[0]) << exact(robot.compliance_deg_per_knm[1])
      << YAML::EndSeq;
  const ModelTolerances& t = robot.tolerance;
  y << YAML::Key << "model_tolerance" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "length_mm" << YAML::Value << exact(t.length_mm);
  y << YAML::Key << "angle_deg" << YAML::Value << exact(t.angle_deg);
  if (anyCounted(t.sag_deg))
    y << YAML::Key << "sag_deg" << YAML::Value << YAML::Flow << YAML::BeginSeq
      << exact(t.sag_deg[0]) << exact(t.sag_deg[1]) << YAML::EndSeq;
  if (anyCounted(t.sag_mean_deg))
    y << YAML::Key << "sag_mean_deg" << YAML::Value << YAML::Flow << YAML::BeginSeq
      << exact(t.sag_mean_deg[0]) << exact(t.sag_mean_deg[1]) << YAML::EndSeq;
  if (t.calibrated()) {
    y << YAML::Key << "link_covariance" << YAML::Value << YAML::BeginSeq;
    for (int r = 0; r < kLinkParameterCount; ++r) {
      y << YAML::Flow << YAML::BeginSeq;
      for (int k = 0; k < kLinkParameterCount; ++k)
        y << exact(t.link_covariance(r, k) / (fileUnit(r) * fileUnit(k)));
      y << YAML::EndSeq;
    }
    y << YAML::EndSeq;
  }
  y << YAML::EndMap << YAML::EndMap;
  if (!y.good()) throw Error(std::string("cannot write the robot file: ") + y.GetLastError());
  o << y.c_str() << "\n";
  return o.str();
}

Eigen::VectorXd ModelTolerances::linkSigmas() const {
  if (calibrated()) return link_covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  Eigen::VectorXd sigma(kLinkParameterCount);
  for (int k = 0; k < kLinkParameterCount; ++k)
    sigma[k] = k % 3 == 2 ? angle_deg * kDegToRad : length_mm;  // a, d in mm; alpha in rad
  return sigma;
}

Eigen::Matrix2d ModelTolerances::sagRootDeg() const {
  Eigen::Matrix2d moment;
  moment << sag_deg[0] * sag_deg[0], sag_mean_deg[0] * sag_mean_deg[1],
      sag_mean_deg[0] * sag_mean_deg[1], sag_deg[1] * sag_deg[1];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(moment);
  return eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

Robot loadRobot(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, {"cannot open the robot file"});
  std::stringstream text;
  text << in.rdbuf();
  return parseRobot(text.str(), path);
}

Frame<double> flangePoseDeg(const Robot& robot, const Joints& q_deg, const Joints& delta_deg) {
  const Joints sag = complianceDeflectionDeg(robot, q_deg);
  double rad[kJointCount];
  for (int i = 0; i < kJointCount; ++i) rad[i] = (q_deg[i] + delta_deg[i] + sag[i]) * kDegToRad;
  return flangePose(robot, rad);
}

std::string checkedRobotYaml(const Robot& robot, const std::string& comment) {
  std::string text = robotYaml(robot, comment);
  parseRobot(text, "the calibrated model written for " + robot.name);
  return text;
}

}  // namespace zerocal
