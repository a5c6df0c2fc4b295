// The simulated cell's ground truth: what calibration must recover (true joint offsets, the true
// laser line) and what it may not know (the true PSD pose), plus the noise the simulators add.
// Frames: base = robot base, flange = DH frame 6 (tool0), PSD = a frame whose z = 0 plane is the
// detector surface, u along its x axis and v along its y axis. Millimetres and degrees.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>

#include "zerocal/model/robot.h"

namespace zerocal {

struct WorldNoise {
  // Standard deviation of the joint-space error added to the true pose on every move (deg).
  // 1.5e-3 deg per joint is 0.020 mm per axis at the TCP (flange), averaged over optimal plans
  // (issue 5: "robot repeatability 0.02 mm sigma"; measured by world_test's
  // DefaultRepeatability test). Seen at the PSD it is about 0.022 mm (chi2/dof 1.24 with a
  // measurement sigma of 0.020 mm, `zerocal experiment cell --worlds 30 --seed0 11`).
  double repeatability_deg = 1.5e-3;
  // Standard deviation of a PSD reading (mm); applied by the PSD simulator, not here.
  double psd_mm = 0.001;
};

struct World {
  Robot robot;
  // Added to the controller's joint angles to get the true ones (deg).
  Joints true_offsets_deg{};
  // The beam in the flange frame: a point on it (mm) and its unit direction.
  Eigen::Vector3d laser_point_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d laser_direction = Eigen::Vector3d::UnitX();
  // The PSD frame in the base frame: x_base = psd_rotation * x_psd + psd_position_mm.
  Eigen::Vector3d psd_position_mm = Eigen::Vector3d(900, -50, 400);
  Eigen::Matrix3d psd_rotation = Eigen::Matrix3d::Identity();
  WorldNoise noise;
};

// Where the beam crosses the PSD plane.
struct BeamHit {
  double u_mm = 0;      // PSD frame x
  double v_mm = 0;      // PSD frame y
  double range_mm = 0;  // from the laser point to the hit, along the beam
};

// The true beam for controller joints q_deg (true angles = q_deg + true offsets + extra_deg, the
// last being e.g. the repeatability error of the current move) meets the PSD plane; nullopt when
// the beam is parallel to the plane or points away from it.
std::optional<BeamHit> beamHit(const World& world, const Joints& q_deg,
                               const Joints& extra_deg = Joints{});

// A fingerprint of everything that makes a world (robot, offsets, laser, PSD pose, noise), as 16
// hex digits: equal for the same seed or the same world file on every build of this code, so two
// processes can check that they simulate the same cell.
std::string worldHash(const World& world);

// Reads a world file (config/worlds/example.yaml):
//   robot: builtin                      # or a robot file, relative to the world file's folder
//   true_offsets_deg: [6 numbers]
//   laser: {point_mm: [x, y, z], direction: [x, y, z]}          # flange frame
//   psd: {position_mm: [x, y, z], rpy_deg: [roll, pitch, yaw]}  # base frame, R = Rz Ry Rx
//   noise: {repeatability_deg: 1.5e-3, psd_mm: 0.001}           # optional
// Throws ConfigError listing every problem found.
World loadWorld(const std::string& path);
World parseWorld(const std::string& yaml_text, const std::string& origin,
                 const std::string& base_dir = ".");

// A random but plausible world, the same for the same seed: the built-in IRB1600, offsets
// uniform in +-1 deg, a laser near the flange x axis, the PSD facing up near (900, -50, 400) mm
// with a tilt of up to 10 deg.
World randomWorld(std::uint64_t seed);

}  // namespace zerocal
