#include "zerocal/sim/world.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {

std::optional<BeamHit> beamHit(const World& world, const Joints& q_deg, const Joints& extra_deg) {
  Joints delta;
  for (int i = 0; i < kJointCount; ++i) delta[i] = world.true_offsets_deg[i] + extra_deg[i];
  const Frame<double> flange = flangePoseDeg(world.robot, q_deg, delta);
  const Eigen::Vector3d p = flange.apply(world.laser_point_mm);
  const Eigen::Vector3d d = (flange.R * world.laser_direction).normalized();
  const Eigen::Vector3d normal = world.psd_rotation.col(2);
  const double along = normal.dot(d);
  // Grazing beams give huge, meaningless hit points long before exact parallelism.
  if (std::abs(along) < 1e-9) return std::nullopt;
  const double t = normal.dot(world.psd_position_mm - p) / along;
  if (!(t > 0)) return std::nullopt;
  const Eigen::Vector3d local =
      world.psd_rotation.transpose() * (p + t * d - world.psd_position_mm);
  return BeamHit{local.x(), local.y(), t};
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
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

namespace {

class Reader {
 public:
  explicit Reader(std::vector<std::string>* problems) : problems_(problems) {}

  template <int N>
  bool vec(const YAML::Node& map, const std::string& key, const std::string& where,
           Eigen::Matrix<double, N, 1>* out) {
    const YAML::Node node = map[key];
    if (!node) {
      problems_->push_back(where + key + ": missing");
      return false;
    }
    if (!node.IsSequence() || node.size() != N) {
      problems_->push_back(where + key + ": must be a list of " + std::to_string(N) + " numbers");
      return false;
    }
    bool good = true;
    for (int i = 0; i < N; ++i) {
      try {
        (*out)[i] = node[i].as<double>();
        if (!std::isfinite((*out)[i])) throw YAML::Exception(YAML::Mark(), "not finite");
      } catch (const YAML::Exception&) {
        problems_->push_back(where + key + "[" + std::to_string(i) + "]: not a finite number");
        good = false;
      }
    }
    return good;
  }

  void number(const YAML::Node& map, const std::string& key, const std::string& where,
              double* out) {
    const YAML::Node node = map[key];
    if (!node) return;  // optional, keeps the default
    try {
      *out = node.as<double>();
      if (!(*out >= 0) || !std::isfinite(*out))
        problems_->push_back(where + key + ": must be >= 0");
    } catch (const YAML::Exception&) {
      problems_->push_back(where + key + ": not a number");
    }
  }

 private:
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

World parseWorld(const std::string& yaml_text, const std::string& origin,
                 const std::string& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, {std::string("not valid YAML: ") + e.what()});
  }
  if (!root.IsMap()) throw ConfigError(origin, {"the file must be a YAML map"});
  std::vector<std::string> problems;
  Reader read(&problems);
  World w;

  std::string robot = "builtin";
  if (root["robot"]) {
    try {
      robot = root["robot"].as<std::string>();
    } catch (const YAML::Exception&) {
      problems.push_back("robot: must be \"builtin\" or a file path");
    }
  }
  try {
    if (robot == "builtin") {
      w.robot = builtinIrb1600();
    } else {
      w.robot = loadRobot(!robot.empty() && robot[0] == '/' ? robot : base_dir + "/" + robot);
    }
  } catch (const ConfigError& e) {
    for (const auto& p : e.problems()) problems.push_back("robot " + robot + ": " + p);
  }

  Eigen::Matrix<double, 6, 1> offsets;
  if (read.vec<6>(root, "true_offsets_deg", "", &offsets)) {
    for (int i = 0; i < 6; ++i) w.true_offsets_deg[i] = offsets[i];
  }
  const YAML::Node laser = root["laser"];
  if (!laser || !laser.IsMap()) {
    problems.push_back("laser: missing (a map with point_mm and direction)");
  } else {
    read.vec<3>(laser, "point_mm", "laser.", &w.laser_point_mm);
    if (read.vec<3>(laser, "direction", "laser.", &w.laser_direction)) {
      if (w.laser_direction.norm() < 1e-9)
        problems.push_back("laser.direction: zero vector");
      else
        w.laser_direction.normalize();
    }
  }
  const YAML::Node psd = root["psd"];
  if (!psd || !psd.IsMap()) {
    problems.push_back("psd: missing (a map with position_mm and rpy_deg)");
  } else {
    read.vec<3>(psd, "position_mm", "psd.", &w.psd_position_mm);
    Eigen::Vector3d angles;
    if (read.vec<3>(psd, "rpy_deg", "psd.", &angles)) w.psd_rotation = rpy(angles);
  }
  if (const YAML::Node noise = root["noise"]) {
    read.number(noise, "repeatability_deg", "noise.", &w.noise.repeatability_deg);
    read.number(noise, "psd_mm", "noise.", &w.noise.psd_mm);
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

World randomWorld(std::uint64_t seed) {
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
  return w;
}

}  // namespace zerocal
