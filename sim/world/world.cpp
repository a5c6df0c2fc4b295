#include "zerocal/sim/world.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/gravity.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {

namespace {

// The true arm's DH table at time_s: the nominal rows plus the link errors, every length grown
// by the thermal state.
std::array<DhRow, kJointCount> trueDh(const World& w, double time_s) {
  const ThermalDrift& t = w.thermal;
  double growth = 1.0;
  if (t.rise_k != 0 && t.time_constant_s > 0 && time_s > 0)
    growth += t.expansion_per_k * t.rise_k * (1.0 - std::exp(-time_s / t.time_constant_s));
  std::array<DhRow, kJointCount> dh = w.robot.dh;
  for (int i = 0; i < kJointCount; ++i) {
    const DhError& e = w.dh_errors[i];
    dh[i].a_mm = (dh[i].a_mm + e.a_mm) * growth;
    dh[i].d_mm = (dh[i].d_mm + e.d_mm) * growth;
    dh[i].alpha_rad += e.alpha_deg * kDegToRad;
  }
  return dh;
}

// The flange of the true arm at controller joints q_deg with `delta_deg` added to every joint.
Frame<double> trueFlange(const World& w, const Joints& q_deg, const Joints& delta_deg,
                         double time_s) {
  const std::array<DhRow, kJointCount> dh = trueDh(w, time_s);
  const Joints sag = gravitySagDeg(w, q_deg);
  const auto rad = [&](int i) { return (q_deg[i] + (delta_deg[i] + sag[i])) * kDegToRad; };
  Frame<double> f = dhLink(dh[0], rad(0));
  for (int i = 1; i < kJointCount; ++i) f = f * dhLink(dh[i], rad(i));
  return f;
}

}  // namespace

namespace {

// The world's three lumped masses (trueMasses), in a fixed array: beamHit allocates nothing.
std::array<LumpedMass, 3> trueMassArray(const World& w) {
  const Compliance& c = w.compliance;
  // A link's mass between the axis of its joint (the previous frame's origin, seen from the
  // link's frame) and the next axis; the forearm's reaches the wrist centre (frame 4's origin).
  const auto between = [](const Eigen::Vector3d& from, const Eigen::Vector3d& to, double at) {
    const Eigen::Vector3d p = from + at * (to - from);
    return std::array<double, 3>{p.x(), p.y(), p.z()};
  };
  const auto previousOrigin = [&](int joint) {
    const Frame<double> f = dhLink(w.robot.dh[joint - 1], 0.0);
    return Eigen::Vector3d(-f.R.transpose() * f.p);
  };
  const Eigen::Vector3d wrist_in_3 = dhLink(w.robot.dh[3], 0.0).p;
  std::array<LumpedMass, 3> out;
  out[0] = {2, c.mass_share[0],
            between(previousOrigin(2), Eigen::Vector3d::Zero(), c.mass_position[0])};
  out[1] = {3, c.mass_share[1], between(previousOrigin(3), wrist_in_3, c.mass_position[1])};
  out[2] = {6, c.mass_share[2], {0, 0, 0}};
  return out;
}

}  // namespace

std::vector<LumpedMass> trueMasses(const World& w) {
  const std::array<LumpedMass, 3> masses = trueMassArray(w);
  return {masses.begin(), masses.end()};
}

Joints gravitySagDeg(const World& w, const Joints& q_deg) {
  Joints sag{};
  const Compliance& c = w.compliance;
  if (c.joint2_sag_deg == 0 && c.joint3_sag_deg == 0) return sag;
  // On the nominal arm: the sag is far too small to move the masses.
  const std::array<LumpedMass, 3> masses = trueMassArray(w);
  const auto torque = gravityTorqueKnm(w.robot, masses.data(), masses.size(), q_deg);
  const auto bound = gravityTorqueBoundKnm(w.robot, masses.data(), masses.size());
  const double sag_deg[kComplianceCount] = {c.joint2_sag_deg, c.joint3_sag_deg};
  for (int k = 0; k < kComplianceCount; ++k)
    sag[k + 1] = bound[k] > 0 ? sag_deg[k] * torque[k] / bound[k] : 0.0;
  return sag;
}

Eigen::Vector3d trueFlangePositionMm(const World& w, const Joints& q_deg, double time_s) {
  return trueFlange(w, q_deg, w.true_offsets_deg, time_s).p;
}

std::optional<BeamHit> beamHit(const World& world, const Joints& q_deg, const Joints& extra_deg,
                               double time_s) {
  Joints delta;
  for (int i = 0; i < kJointCount; ++i) delta[i] = world.true_offsets_deg[i] + extra_deg[i];
  const Frame<double> flange = trueFlange(world, q_deg, delta, time_s);
  const Eigen::Vector3d p = flange.apply(world.laser_point_mm);
  const Eigen::Vector3d d = (flange.R * world.laser_direction).normalized();
  Eigen::Vector3d position = world.psd_position_mm + world.psd_seated_mm;
  const Eigen::Matrix3d* rotation = &world.psd_rotation;
  for (const PsdPlacement& placed : world.placements)
    if (placed.placement == world.active_placement) {
      position = placed.position_mm;
      rotation = &placed.rotation;
    }
  const Eigen::Vector3d normal = rotation->col(2);
  const double along = normal.dot(d);
  // Grazing beams give huge, meaningless hit points long before exact parallelism.
  if (std::abs(along) < 1e-9) return std::nullopt;
  const double t = normal.dot(position - p) / along;
  if (!(t > 0)) return std::nullopt;
  const Eigen::Vector3d local = rotation->transpose() * (p + t * d - position);
  return BeamHit{{local.x(), local.y()}, t};
}

const char* grossKindName(GrossErrors::Kind kind) {
  return kind == GrossErrors::Kind::kUnsettled ? "unsettled" : "stray_light";
}

GrossErrors::Kind parseGrossKind(const std::string& word) {
  if (word == "stray_light") return GrossErrors::Kind::kStrayLight;
  if (word == "unsettled") return GrossErrors::Kind::kUnsettled;
  throw InputError("'" + word + "' is not a kind of gross error: stray_light or unsettled");
}

void updateGross(const GrossErrors& gross, const Joints& q_deg, std::mt19937_64& rng,
                 GrossState* state) {
  // The forced error's pose is the one the arm comes to rest at within a fraction of a degree,
  // not any pose within the extent of it: another plan pose a few degrees away would otherwise
  // take the error first.
  bool forced = false;
  if (gross.forced_at_deg && !state->forced_done) {
    double off = 0;
    for (int i = 0; i < kJointCount; ++i)
      off = std::max(off, std::abs(q_deg[i] - (*gross.forced_at_deg)[i]));
    forced = state->forced_done = off <= kForcedPoseMatchDeg;
  }
  if (state->anchored && !forced) {
    double moved = 0;
    for (int i = 0; i < kJointCount; ++i)
      moved = std::max(moved, std::abs(q_deg[i] - state->anchor_deg[i]));
    if (moved <= kGrossPoseExtentDeg) return;
  }
  state->anchored = true;
  state->anchor_deg = q_deg;
  ++state->draws;
  // Always the same five draws, so that one kind's rate does not change the other's sequence.
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double stray = unit(rng), angle = 2 * kPi * unit(rng);
  const double unsettled = unit(rng), which = unit(rng), sign = unit(rng);
  const bool forced_stray = forced && gross.forced_kind == GrossErrors::Kind::kStrayLight;
  const bool forced_unsettled = forced && gross.forced_kind == GrossErrors::Kind::kUnsettled;
  state->stray_light_mm = Eigen::Vector2d::Zero();
  if (stray < gross.stray_light_rate || forced_stray)
    state->stray_light_mm =
        gross.stray_light_mm * Eigen::Vector2d(std::cos(angle), std::sin(angle));
  state->unsettled_deg = Joints{};
  if (unsettled < gross.unsettled_rate || forced_unsettled) {
    const int joint = std::min(kJointCount - 1, static_cast<int>(which * kJointCount));
    state->unsettled_deg[joint] = sign < 0.5 ? -gross.unsettled_deg : gross.unsettled_deg;
  }
}

std::string worldHash(const World& w) {
  // FNV-1a over the values' bytes: both sides build the world with the same code, so equal
  // worlds are bit-equal.
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](const void* data, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  const auto value = [&mix](double v) { mix(&v, sizeof v); };
  mix(w.robot.name.data(), w.robot.name.size());
  for (int i = 0; i < kJointCount; ++i) {
    const DhRow& r = w.robot.dh[i];
    mix(&r, sizeof r);
    value(w.robot.limits[i].lower_deg);
    value(w.robot.limits[i].upper_deg);
    value(w.robot.max_speed_deg_s[i]);
    value(w.true_offsets_deg[i]);
  }
  for (int i = 0; i < 3; ++i) {
    value(w.laser_point_mm[i]);
    value(w.laser_direction[i]);
    value(w.psd_position_mm[i]);
    for (int j = 0; j < 3; ++j) value(w.psd_rotation(i, j));
  }
  value(w.noise.repeatability_deg);
  value(w.noise.psd_mm);
  for (const DhError& e : w.dh_errors) {
    value(e.a_mm);
    value(e.d_mm);
    value(e.alpha_deg);
  }
  value(w.compliance.joint2_sag_deg);
  value(w.compliance.joint3_sag_deg);
  // The masses shape a sag only where there is one (and so the hash of a world without sag,
  // the ideal one, is what it was before they existed).
  if (w.compliance.joint2_sag_deg != 0 || w.compliance.joint3_sag_deg != 0) {
    for (double v : w.compliance.mass_share) value(v);
    for (double v : w.compliance.mass_position) value(v);
  }
  value(w.thermal.expansion_per_k);
  value(w.thermal.rise_k);
  value(w.thermal.time_constant_s);
  for (int i = 0; i < 3; ++i) {
    value(w.psd_centre_taught_mm[i]);
    for (int j = 0; j < 3; ++j) value(w.psd_rotation_configured(i, j));
  }
  value(w.gross.stray_light_rate);
  value(w.gross.stray_light_mm);
  value(w.gross.unsettled_rate);
  value(w.gross.unsettled_deg);
  if (w.gross.forced_at_deg) {  // mixed in only when set: every other world keeps its hash
    for (const double q : *w.gross.forced_at_deg) value(q);
    value(static_cast<int>(w.gross.forced_kind));
  }
  return fmt::format(FMT_STRING("{:016x}"), h);
}

namespace {

// Bounds of a world's numbers: what a cell can have. Beyond them a value is a typing error
// whose arithmetic (a square of 1e200, a cast of 1e300) would be meaningless.
constexpr double kMaxPositionMm = 10000;  // the cell: 10 m from the robot's base
constexpr double kMaxAngleDeg = 360;
constexpr double kMaxDirection = 1e6;  // a direction is normalised; its square must stay finite
constexpr double kMaxLinkErrorMm = 1000, kMaxLinkErrorDeg = 90;
constexpr double kMaxSpotMm = 50;  // a few tens of mm: the largest detectors
constexpr double kMaxSeatMm = 1;   // beyond, the PSD is not seated again but moved

// Reads the file's values, recording each problem as "file:line: key: what" instead of throwing.
// A value is read from a map only: indexing a scalar or a list throws in yaml-cpp, so a section
// that is not a map is one problem and its keys are not looked at.
class Reader {
 public:
  Reader(std::string origin, std::vector<std::string>* problems)
      : origin_(std::move(origin)), problems_(problems) {}

  void problem(const YAML::Node& near, const std::string& what) {
    problem(near && near.IsDefined() ? near.Mark() : YAML::Mark::null_mark(), what);
  }
  void problem(const YAML::Mark& mark, const std::string& what) {
    problems_->push_back(origin_ + (mark.is_null() ? "" : ":" + std::to_string(mark.line + 1)) +
                         ": " + what);
  }

  // root[key] when it is a map; a problem, and an undefined node (false, as an absent key's),
  // when it is something else.
  YAML::Node section(const YAML::Node& root, const std::string& key) {
    const YAML::Node node = root[key];
    if (!node || node.IsMap()) return node;
    problem(node, key + ": must be a map");
    return YAML::Node(YAML::NodeType::Undefined);
  }

  template <int N>
  bool vec(const YAML::Node& map, const std::string& key, const std::string& where, double bound,
           Eigen::Matrix<double, N, 1>* out) {
    const YAML::Node node = map.IsMap() ? map[key] : YAML::Node();
    if (!node) {
      problem(map, where + key + ": missing");
      return false;
    }
    if (!node.IsSequence() || node.size() != N) {
      problem(node, where + key + ": must be a list of " + std::to_string(N) + " numbers");
      return false;
    }
    bool good = true;
    for (int i = 0; i < N; ++i) {
      double v = 0;
      if (!real(node[i], &v) || !(std::abs(v) <= bound)) {
        problem(node[i], where + key + "[" + std::to_string(i) + "]: must be a number within +-" +
                             format(bound));
        good = false;
      } else {
        (*out)[i] = v;
      }
    }
    return good;
  }

  // As vec(), but an absent key keeps *out and is no problem.
  template <int N>
  bool optionalVec(const YAML::Node& map, const std::string& key, const std::string& where,
                   double bound, Eigen::Matrix<double, N, 1>* out) {
    return map.IsMap() && map[key] ? vec<N>(map, key, where, bound, out) : false;
  }

  // Only the keys named may appear in the map.
  void onlyKeys(const YAML::Node& map, const std::string& where,
                std::initializer_list<const char*> keys) {
    if (!map.IsMap()) {
      problem(map, where + ": must be a map");
      return;
    }
    for (const auto& entry : map) {
      const std::string key = entry.first.IsScalar() ? entry.first.Scalar() : "(not a word)";
      if (std::none_of(keys.begin(), keys.end(), [&](const char* k) { return key == k; }))
        problem(entry.first, where + (where.empty() ? "" : ".") + key + ": unknown key");
    }
  }

  // An optional number within 0..bound; absent, *out keeps its default.
  void number(const YAML::Node& map, const std::string& key, const std::string& where, double bound,
              double* out) {
    if (!map.IsMap()) return;
    const YAML::Node node = map[key];
    if (!node) return;  // optional, keeps the default
    double v = 0;
    if (!real(node, &v))
      problem(node, where + key + ": not a number");
    else if (!(v >= 0 && v <= bound))
      problem(node, where + key + ": must lie within 0.." + format(bound));
    else
      *out = v;
  }

 private:
  static bool real(const YAML::Node& node, double* out) {
    if (!node.IsScalar()) return false;
    try {
      *out = node.as<double>();
      return std::isfinite(*out);
    } catch (const YAML::Exception&) {
      return false;
    }
  }
  static std::string format(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  }

  std::string origin_;
  std::vector<std::string>* problems_;
};

Eigen::Matrix3d rpy(const Eigen::Vector3d& rpy_deg) {
  const Eigen::Vector3d r = rpy_deg * kDegToRad;
  return (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace

namespace {

void readWorld(const YAML::Node& root, const std::string& base_dir, Reader& read, World& w) {
  std::string robot = "builtin";
  if (const YAML::Node r = root["robot"]) {
    if (r.IsScalar())
      robot = r.Scalar();
    else
      read.problem(r, "robot: must be \"builtin\" or a file path");
  }
  try {
    if (robot == "builtin") {
      w.robot = builtinIrb1600();
    } else {
      w.robot = loadRobot(!robot.empty() && robot[0] == '/' ? robot : base_dir + "/" + robot);
    }
  } catch (const ConfigError& e) {
    for (const auto& p : e.problems()) read.problem(root["robot"], "robot: " + p);
  }

  Eigen::Matrix<double, 6, 1> offsets;
  if (read.vec<6>(root, "true_offsets_deg", "", kMaxAngleDeg, &offsets)) {
    for (int i = 0; i < 6; ++i) w.true_offsets_deg[i] = offsets[i];
  }
  const YAML::Node laser = read.section(root, "laser");
  if (!laser) {
    if (!root["laser"]) read.problem(root, "laser: missing (a map with point_mm and direction)");
  } else {
    read.vec<3>(laser, "point_mm", "laser.", kMaxPositionMm, &w.laser_point_mm);
    if (read.vec<3>(laser, "direction", "laser.", kMaxDirection, &w.laser_direction)) {
      if (w.laser_direction.norm() < 1e-9)
        read.problem(laser["direction"], "laser.direction: zero vector");
      else
        w.laser_direction.normalize();
    }
  }
  const YAML::Node psd = read.section(root, "psd");
  if (!psd) {
    if (!root["psd"]) read.problem(root, "psd: missing (a map with position_mm and rpy_deg)");
  } else {
    read.vec<3>(psd, "position_mm", "psd.", kMaxPositionMm, &w.psd_position_mm);
    Eigen::Vector3d angles;
    if (read.vec<3>(psd, "rpy_deg", "psd.", kMaxAngleDeg, &angles)) w.psd_rotation = rpy(angles);
  }
  if (const YAML::Node noise = read.section(root, "noise")) {
    read.onlyKeys(noise, "noise", {"repeatability_deg", "psd_mm", "psd_seat_mm", "seed"});
    read.number(noise, "repeatability_deg", "noise.", kMaxAngleDeg, &w.noise.repeatability_deg);
    read.number(noise, "psd_mm", "noise.", kMaxSpotMm, &w.noise.psd_mm);
    read.number(noise, "psd_seat_mm", "noise.", kMaxSeatMm, &w.noise.psd_seat_mm);
    if (const YAML::Node seed = noise["seed"]) {
      // A seed is a whole number of 64 bits; a sign or a fraction is a typing error.
      const std::string text = seed.IsScalar() ? seed.Scalar() : "";
      char* end = nullptr;
      errno = 0;
      const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
      if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0])) || *end != '\0' ||
          errno == ERANGE)
        read.problem(seed, "noise.seed: must be a whole number 0..18446744073709551615");
      else
        w.noise.seed = v;
    }
  }
  read.onlyKeys(root, "",
                {"robot", "true_offsets_deg", "laser", "psd", "noise", "dh_errors", "compliance",
                 "thermal", "gross_errors", "placements"});
  if (psd) {
    read.onlyKeys(psd, "psd", {"position_mm", "rpy_deg", "configured_rpy_deg", "taught_centre_mm"});
    w.psd_rotation_configured = w.psd_rotation;
    w.psd_centre_taught_mm = w.psd_position_mm + Eigen::Vector3d(3, -3, 3);
    Eigen::Vector3d configured;
    if (read.optionalVec<3>(psd, "configured_rpy_deg", "psd.", kMaxAngleDeg, &configured))
      w.psd_rotation_configured = rpy(configured);
    read.optionalVec<3>(psd, "taught_centre_mm", "psd.", kMaxPositionMm, &w.psd_centre_taught_mm);
  }
  if (const YAML::Node links = read.section(root, "dh_errors")) {
    read.onlyKeys(links, "dh_errors", {"a_mm", "d_mm", "alpha_deg"});
    Eigen::Matrix<double, 6, 1> v;
    if (read.optionalVec<6>(links, "a_mm", "dh_errors.", kMaxLinkErrorMm, &v))
      for (int i = 0; i < 6; ++i) w.dh_errors[i].a_mm = v[i];
    if (read.optionalVec<6>(links, "d_mm", "dh_errors.", kMaxLinkErrorMm, &v))
      for (int i = 0; i < 6; ++i) w.dh_errors[i].d_mm = v[i];
    if (read.optionalVec<6>(links, "alpha_deg", "dh_errors.", kMaxLinkErrorDeg, &v))
      for (int i = 0; i < 6; ++i) w.dh_errors[i].alpha_deg = v[i];
  }
  if (const YAML::Node c = read.section(root, "compliance")) {
    read.onlyKeys(c, "compliance",
                  {"joint2_sag_deg", "joint3_sag_deg", "mass_share", "mass_position"});
    read.number(c, "joint2_sag_deg", "compliance.", kMaxAngleDeg, &w.compliance.joint2_sag_deg);
    read.number(c, "joint3_sag_deg", "compliance.", kMaxAngleDeg, &w.compliance.joint3_sag_deg);
    Eigen::Vector3d share;
    if (read.optionalVec<3>(c, "mass_share", "compliance.", 1e6, &share)) {
      if (!(share.minCoeff() > 0))
        read.problem(c["mass_share"], "compliance.mass_share: must be > 0");
      for (int i = 0; i < 3; ++i) w.compliance.mass_share[i] = share[i];
    }
    Eigen::Vector2d position;
    if (read.optionalVec<2>(c, "mass_position", "compliance.", 1, &position)) {
      if (!(position.minCoeff() >= 0 && position.maxCoeff() <= 1))
        read.problem(c["mass_position"], "compliance.mass_position: must lie within 0..1");
      for (int i = 0; i < 2; ++i) w.compliance.mass_position[i] = position[i];
    }
  }
  if (const YAML::Node t = read.section(root, "thermal")) {
    read.onlyKeys(t, "thermal", {"expansion_per_k", "rise_k", "time_constant_s"});
    // Bounds far beyond any metal (aluminium 23e-6 per K), any cell's warming, any day.
    read.number(t, "expansion_per_k", "thermal.", 1e-3, &w.thermal.expansion_per_k);
    read.number(t, "rise_k", "thermal.", 1000, &w.thermal.rise_k);
    read.number(t, "time_constant_s", "thermal.", 1e7, &w.thermal.time_constant_s);
    if (!(w.thermal.time_constant_s > 0))
      read.problem(t["time_constant_s"] ? t["time_constant_s"] : t,
                   "thermal.time_constant_s: must be > 0");
  }
  if (const YAML::Node g = read.section(root, "gross_errors")) {
    read.onlyKeys(g, "gross_errors",
                  {"stray_light_rate", "stray_light_mm", "unsettled_rate", "unsettled_deg",
                   "forced_at_deg", "forced_kind"});
    read.number(g, "stray_light_rate", "gross_errors.", 1, &w.gross.stray_light_rate);
    read.number(g, "stray_light_mm", "gross_errors.", kMaxSpotMm, &w.gross.stray_light_mm);
    read.number(g, "unsettled_rate", "gross_errors.", 1, &w.gross.unsettled_rate);
    read.number(g, "unsettled_deg", "gross_errors.", kMaxAngleDeg, &w.gross.unsettled_deg);
    Eigen::Matrix<double, kJointCount, 1> q;
    if (read.optionalVec<kJointCount>(g, "forced_at_deg", "gross_errors.", kMaxJointTravelDeg,
                                      &q)) {
      w.gross.forced_at_deg = Joints{};
      for (int i = 0; i < kJointCount; ++i) (*w.gross.forced_at_deg)[i] = q[i];
    }
    if (const YAML::Node k = g["forced_kind"]) {
      try {
        w.gross.forced_kind = parseGrossKind(k.IsScalar() ? k.Scalar() : "");
      } catch (const InputError& e) {
        read.problem(k, std::string("gross_errors.forced_kind: ") + e.what());
      }
    }
  }
  if (const YAML::Node placements = root["placements"]) {
    if (!placements.IsSequence()) read.problem(placements, "placements: expected a list");
    for (std::size_t i = 0; placements.IsSequence() && i < placements.size(); ++i) {
      const YAML::Node p = placements[i];
      const std::string where = "placements[" + std::to_string(i) + "].";
      if (!p.IsMap()) {
        read.problem(p, where + ": expected a map");
        continue;
      }
      read.onlyKeys(p, "placements[" + std::to_string(i) + "]",
                    {"placement", "planned_mm", "position_mm", "rpy_deg"});
      PsdPlacement placed;
      double number = 0;
      read.number(p, "placement", where, 100, &number);
      // Checked before the cast: a double beyond int has no int to become.
      if (number != std::floor(number) || number < 2 || number > 100)
        read.problem(p["placement"] ? p["placement"] : p,
                     where + "placement: must be a whole number 2..100");
      else
        placed.placement = static_cast<int>(number);
      read.vec<3>(p, "planned_mm", where, kMaxPositionMm, &placed.planned_mm);
      read.vec<3>(p, "position_mm", where, kMaxPositionMm, &placed.position_mm);
      Eigen::Vector3d angles;
      if (read.vec<3>(p, "rpy_deg", where, kMaxAngleDeg, &angles)) placed.rotation = rpy(angles);
      w.placements.push_back(placed);
    }
  }
}

}  // namespace

std::uint64_t sessionNoiseSeed(std::uint64_t first, std::uint64_t session) {
  if (session == 0) return first;
  // splitmix64 of the pair: neighbouring sessions (and neighbouring worlds' sessions) get
  // unrelated streams, and no later session's seed is a plain small number another world uses.
  std::uint64_t z = first + 0x9e3779b97f4a7c15ull * (session + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

void applyZeroChange(const ZeroChange& change, World* world) {
  const std::string problem = zeroChangeProblem(change);
  if (!problem.empty()) throw InputError("zero change: " + problem);
  if (change.joint != 0) world->true_offsets_deg[change.joint - 1] += change.deg;
}

void applyRemount(const Remount& psd, const Remount& laser, World* world) {
  for (const std::string& problem : {remountMoveProblem(psd), remountTurnProblem(psd),
                                     remountMoveProblem(laser), remountTurnProblem(laser)})
    if (!problem.empty()) throw InputError("re-mount: " + problem);
  const auto vec = [](const std::array<double, 3>& a) { return Eigen::Vector3d(a[0], a[1], a[2]); };
  // Nothing re-mounted leaves the world bit for bit as it was (its hash names it to zerocal-sim).
  if (psd.any()) {
    world->psd_position_mm += vec(psd.moved_mm);
    world->psd_rotation = rpy(vec(psd.turned_deg)) * world->psd_rotation;
  }
  if (laser.any()) {
    world->laser_point_mm += vec(laser.moved_mm);
    world->laser_direction = (rpy(vec(laser.turned_deg)) * world->laser_direction).normalized();
  }
}

World parseWorld(const std::string& yaml_text, const std::string& origin,
                 const std::string& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin,
                      {origin + (e.mark.is_null() ? "" : ":" + std::to_string(e.mark.line + 1)) +
                       ": not valid YAML: " + e.msg});
  }
  if (!root.IsMap()) throw ConfigError(origin, {origin + ": the file must be a YAML map"});
  std::vector<std::string> problems;
  Reader read(origin, &problems);
  World w;
  try {
    readWorld(root, base_dir, read, w);
  } catch (const YAML::Exception& e) {
    // Every read above checks the shape it reads; whatever slips past is the file's fault
    // still, never a crash.
    read.problem(e.mark, "unexpected structure: " + e.msg);
  }
  if (!problems.empty()) throw ConfigError(origin, problems);
  return w;
}

World loadWorld(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, {"cannot open the file"});
  std::stringstream text;
  text << in.rdbuf();
  const std::size_t slash = path.rfind('/');
  return parseWorld(text.str(), path, slash == std::string::npos ? "." : path.substr(0, slash));
}

World randomWorld(std::uint64_t seed, WorldKind kind) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  World w;
  w.robot = builtinIrb1600();
  for (double& d : w.true_offsets_deg) d = unit(rng);
  // A laser clamped roughly along the flange x axis, a few mm off it: the nominal LaserModel.
  w.laser_point_mm = Eigen::Vector3d(0, 5 * unit(rng), 5 * unit(rng));
  w.laser_direction = Eigen::Vector3d(1, 0.02 * unit(rng), 0.02 * unit(rng)).normalized();
  w.psd_position_mm =
      Eigen::Vector3d(900 + 20 * unit(rng), -50 + 20 * unit(rng), 400 + 20 * unit(rng));
  w.psd_rotation = rpy(Eigen::Vector3d(10 * unit(rng), 10 * unit(rng), 180 * unit(rng)));
  w.psd_rotation_configured = w.psd_rotation;
  w.psd_centre_taught_mm = w.psd_position_mm + Eigen::Vector3d(3, -3, 3);
  if (kind == WorldKind::kIdeal) {
    // The ideal arm is the robot file's exactly, without sag: the model a session is given
    // (knowledgeOf) admits no error, and nothing is counted for one.
    w.robot.tolerance = {};
    return w;
  }

  // The imperfections from their own stream: the ideal world of a seed stays what it was, and
  // the realistic one shares its offsets, laser and PSD pose. Magnitudes: docs/simulated-cell.md.
  std::mt19937_64 more(seed ^ 0x7265616c69737469ull);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> zero_one(0.0, 1.0);
  const auto between = [&](double lo, double hi) { return lo + (hi - lo) * zero_one(more); };
  const auto direction = [&] {
    Eigen::Vector3d v;
    do v = Eigen::Vector3d(normal(more), normal(more), normal(more));
    while (v.norm() < 1e-6);
    return v.normalized();
  };
  for (DhError& e : w.dh_errors) {
    e.a_mm = kLinkLengthSigmaMm * normal(more);
    e.d_mm = kLinkLengthSigmaMm * normal(more);
    e.alpha_deg = kLinkTwistSigmaDeg * normal(more);
  }
  w.compliance.joint2_sag_deg = between(0.003, 0.010);
  w.compliance.joint3_sag_deg = between(0.002, 0.006);
  w.thermal.expansion_per_k = 23e-6;  // aluminium
  w.thermal.rise_k = between(3, 10);
  w.thermal.time_constant_s = between(1800, 7200);
  const double psd_angle_deg = between(1, 3);
  w.psd_rotation_configured =
      w.psd_rotation * Eigen::AngleAxisd(psd_angle_deg * kDegToRad, direction()).toRotationMatrix();
  w.psd_centre_taught_mm = w.psd_position_mm + between(1, 5) * direction();
  w.gross.stray_light_rate = kDefaultGrossRate;
  w.gross.unsettled_rate = kDefaultGrossRate;
  w.noise.psd_seat_mm = kPsdSeatSigmaMm;
  // Drawn last, so that every draw before stays what it was: the masses' split +-25% of each
  // share and their places +-0.1 of their link around the robot file's nominal model.
  double total = 0;
  for (double& s : w.compliance.mass_share) total += s *= 1 + kMassShareSpread * unit(more);
  for (double& s : w.compliance.mass_share) s /= total;
  for (double& p : w.compliance.mass_position) p += kMassPositionSpread * unit(more);
  return w;
}

PsdPlacement drawPlacement(const World& world, std::uint64_t seed, int placement,
                           const Eigen::Vector3d& planned_mm) {
  std::mt19937_64 rng(seed ^ 0x706c6163656d656eull ^
                      (static_cast<std::uint64_t>(placement) * 0x9e3779b97f4a7c15ull));
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto direction = [&] {
    Eigen::Vector3d v;
    do v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    while (v.norm() < 1e-6);
    return v.normalized();
  };
  const double centre_error_mm = (world.psd_centre_taught_mm - world.psd_position_mm).norm();
  const double angle_rad =
      Eigen::AngleAxisd(world.psd_rotation_configured.transpose() * world.psd_rotation).angle();
  PsdPlacement p;
  p.placement = placement;
  p.planned_mm = planned_mm;
  p.position_mm = planned_mm + centre_error_mm * direction();
  p.rotation =
      world.psd_rotation_configured * Eigen::AngleAxisd(angle_rad, direction()).toRotationMatrix();
  return p;
}

namespace {

Eigen::Vector3d rpyOf(const Eigen::Matrix3d& r) {
  // R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-90, 90] deg.
  return Eigen::Vector3d(std::atan2(r(2, 1), r(2, 2)), std::asin(std::clamp(-r(2, 0), -1.0, 1.0)),
                         std::atan2(r(1, 0), r(0, 0))) *
         kRadToDeg;
}

std::string num(double v) { return fmt::format(FMT_STRING("{:.17g}"), v); }

}  // namespace

std::string worldYaml(const World& w, const std::string& robot_file) {
  // yaml-cpp's emitter quotes what needs it (a robot file's path with ": " or " #" in it);
  // each number is written exactly (17 digits), as text, and a list in flow style.
  YAML::Emitter y;
  const auto list = [&y](const auto& v, int n) {
    y << YAML::Flow << YAML::BeginSeq;
    for (int i = 0; i < n; ++i) y << num(v[i]);
    y << YAML::EndSeq;
  };
  const auto key = [&y](const char* k) -> YAML::Emitter& {
    return y << YAML::Key << k << YAML::Value;
  };
  y << YAML::BeginMap;
  key("robot") << robot_file;
  key("true_offsets_deg");
  list(w.true_offsets_deg, 6);
  key("laser") << YAML::BeginMap;
  key("point_mm");
  list(w.laser_point_mm, 3);
  key("direction");
  list(w.laser_direction, 3);
  y << YAML::EndMap;
  key("psd") << YAML::BeginMap;
  key("position_mm");
  list(w.psd_position_mm, 3);
  key("rpy_deg");
  list(rpyOf(w.psd_rotation), 3);
  key("configured_rpy_deg");
  list(rpyOf(w.psd_rotation_configured), 3);
  key("taught_centre_mm");
  list(w.psd_centre_taught_mm, 3);
  y << YAML::EndMap;
  key("noise") << YAML::BeginMap;
  key("repeatability_deg") << num(w.noise.repeatability_deg);
  key("psd_mm") << num(w.noise.psd_mm);
  if (w.noise.psd_seat_mm != 0) key("psd_seat_mm") << num(w.noise.psd_seat_mm);
  if (w.noise.seed) key("seed") << *w.noise.seed;
  y << YAML::EndMap;
  Joints a, d, alpha;
  for (int i = 0; i < kJointCount; ++i) {
    a[i] = w.dh_errors[i].a_mm;
    d[i] = w.dh_errors[i].d_mm;
    alpha[i] = w.dh_errors[i].alpha_deg;
  }
  key("dh_errors") << YAML::BeginMap;
  key("a_mm");
  list(a, 6);
  key("d_mm");
  list(d, 6);
  key("alpha_deg");
  list(alpha, 6);
  y << YAML::EndMap;
  key("compliance") << YAML::BeginMap;
  key("joint2_sag_deg") << num(w.compliance.joint2_sag_deg);
  key("joint3_sag_deg") << num(w.compliance.joint3_sag_deg);
  key("mass_share");
  list(w.compliance.mass_share, 3);
  key("mass_position");
  list(w.compliance.mass_position, 2);
  y << YAML::EndMap;
  key("thermal") << YAML::BeginMap;
  key("expansion_per_k") << num(w.thermal.expansion_per_k);
  key("rise_k") << num(w.thermal.rise_k);
  key("time_constant_s") << num(w.thermal.time_constant_s);
  y << YAML::EndMap;
  key("gross_errors") << YAML::BeginMap;
  key("stray_light_rate") << num(w.gross.stray_light_rate);
  key("stray_light_mm") << num(w.gross.stray_light_mm);
  key("unsettled_rate") << num(w.gross.unsettled_rate);
  key("unsettled_deg") << num(w.gross.unsettled_deg);
  if (w.gross.forced_at_deg) {
    key("forced_at_deg");
    list(*w.gross.forced_at_deg, kJointCount);
    key("forced_kind") << grossKindName(w.gross.forced_kind);
  }
  y << YAML::EndMap;
  if (!w.placements.empty()) {
    key("placements") << YAML::BeginSeq;
    for (const PsdPlacement& p : w.placements) {
      y << YAML::BeginMap;
      key("placement") << p.placement;
      key("planned_mm");
      list(p.planned_mm, 3);
      key("position_mm");
      list(p.position_mm, 3);
      key("rpy_deg");
      list(rpyOf(p.rotation), 3);
      y << YAML::EndMap;
    }
    y << YAML::EndSeq;
  }
  y << YAML::EndMap;
  if (!y.good()) throw Error(std::string("cannot write the world file: ") + y.GetLastError());
  // The robot's name in a comment: on one line.
  std::string name = w.robot.name;
  std::replace(name.begin(), name.end(), '\n', ' ');
  return "# The truth of a simulated cell (zerocal world file, docs/simulated-cell.md).\n"
         "# world hash " +
         worldHash(w) + " (" + name + ")\n" + y.c_str() + "\n";
}

}  // namespace zerocal
