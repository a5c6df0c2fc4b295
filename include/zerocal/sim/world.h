// The simulated cell's ground truth: what calibration must recover (true joint offsets, the true
// laser line), what it may not know (the true PSD pose, the arm's true geometry and compliance,
// its thermal state), what the technician gives it (the PSD's configured orientation and taught
// centre), plus the noise and the gross errors the simulators add. docs/simulated-cell.md gives
// the evidence for every magnitude.
// Frames: base = robot base, flange = DH frame 6 (tool0), PSD = a frame whose z = 0 plane is the
// detector surface, u along its x axis and v along its y axis. Millimetres, degrees, seconds.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "zerocal/model/robot.h"
#include "zerocal/psd/spot.h"
#include "zerocal/sim/remount.h"
#include "zerocal/sim/zero_change.h"

namespace zerocal {

struct WorldNoise {
  // Standard deviation of the joint-space error added to the true pose on every move (deg).
  // 1.5e-3 deg per joint is 0.020 mm per axis at the TCP (flange), averaged over optimal plans
  // (issue 5: "robot repeatability 0.02 mm sigma"; measured by world_test's
  // DefaultRepeatability test). Seen at the PSD it is about 0.022 mm (chi2/dof 1.24 with a
  // measurement sigma of 0.020 mm, `zerocal-lab experiment cell --worlds 30 --seed0 11`).
  double repeatability_deg = 1.5e-3;
  // Standard deviation of a PSD reading (mm); applied by the PSD simulator, not here.
  double psd_mm = 0.001;
  // How closely the PSD's base puts it back where it stood, one sigma per axis per seating (mm):
  // each session of the in-process simulated cell draws where the PSD sits from its own seed
  // (World::psd_seated_mm), as a technician's PSD taken off and put back on its base between
  // sessions sits. 0: it sits exactly at psd_position_mm every session. Not part of worldHash,
  // as the seed is not (zerocal-sim seats it once, from its --seed).
  double psd_seat_mm = 0;
  // Where a session's random draws start (the repeatability noise, the gross errors, the latch
  // latency, the PSD's reading noise), when the world says: a truth file names the seed its
  // session drew from, so that the file replays that session. Absent, the daemon derives it
  // (sessionNoiseSeed). Not part of worldHash: the same cell, another session.
  std::optional<std::uint64_t> seed;
};

// The noise seed of the session numbered `session` (0, 1, ...: the sessions the data folder held
// before it) of a world whose first session draws from `first`: `first` itself for session 0, so
// that a fresh data folder plays what the world always played; a well-mixed other seed for every
// later one, so that two sessions on one world never share a noise stream.
std::uint64_t sessionNoiseSeed(std::uint64_t first, std::uint64_t session);

// How one link of the true arm differs from the nominal DH row (added to a, d and alpha).
struct DhError {
  double a_mm = 0;
  double d_mm = 0;
  double alpha_deg = 0;
};

// Gravity sag of joints 2 and 3: the gearboxes yield to the gravity torque of the arm beyond
// them, so the true joint angle is the commanded one plus sag * tau(q) / tau_max, tau(q) the
// gravity torque about the joint's axis at pose q (a lumped-mass model of the IRB 1600's arm:
// upper arm, forearm, wrist and tool; gravityTorqueKnm) and tau_max its bound with the arm
// stretched out horizontally (gravityTorqueBoundKnm): a constant compliance.
struct Compliance {
  double joint2_sag_deg = 0;  // at tau_max
  double joint3_sag_deg = 0;
  // The true arm's masses: the shares of the upper arm, the forearm and the wrist with the tool
  // (at the flange) in its moving mass, and where along their link the first two sit (0: at the
  // joint's axis, 1: at the next joint's axis, the forearm's next being the wrist centre). The
  // robot file's gravity model is the nominal (0.4, 0.4, 0.2) at the middles; a real arm's are
  // not known that well, so the realistic world draws them around it.
  std::array<double, 3> mass_share = {0.4, 0.4, 0.2};
  std::array<double, 2> mass_position = {0.5, 0.5};
};

// Thermal growth of the arm: every DH length (a, d) grows by expansion_per_k * dT(t), where
// dT(t) = rise_k * (1 - exp(-t / time_constant_s)) and t is the controller's time (its moves
// since it started, plus the work it had done before when it starts warm: backend.sim_warm_s):
// a cold arm starts at ambient temperature and warms towards rise_k.
struct ThermalDrift {
  double expansion_per_k = 0;
  double rise_k = 0;
  double time_constant_s = 3600;
};
// The longest a simulated controller may have been running when a session starts (s, the arm's
// warm-up carried in: SimulatedArmOptions::warm_s, backend.sim_warm_s): a week, many time
// constants, the arm long at its steady state.
constexpr double kMaxWarmS = 7 * 24 * 3600.0;

// Occasional gross errors, drawn per pose: whenever the arm comes to rest more than
// kGrossPoseExtentDeg (any joint) from the pose of the last draw, each kind happens with its
// rate and lasts while the arm stays near that pose.
struct GrossErrors {
  // Stray light (a reflection off the arm or fixture reaching the detector): the reading's
  // apparent spot is shifted by stray_light_mm in a random direction.
  double stray_light_rate = 0;
  double stray_light_mm = 0.5;
  // A reading taken before the arm settled: the arm is unsettled_deg off its commanded angle on
  // one random joint while the pose is read.
  double unsettled_rate = 0;
  double unsettled_deg = 0.05;
  // Besides the rates: exactly one error of `forced_kind`, the first time the arm comes to rest
  // within kForcedPoseMatchDeg of `forced_at_deg` (the joints a session recorded at a pose: its
  // move ends there or, aimed at a predicted spot, within a fraction of a degree of them).
  // For measuring what a session does with one gross error against the same session without it
  // (`zerocal-lab experiment cell --gross-error`); its direction or joint comes from that pose's
  // own draws (an extra draw when the pose lies within kGrossPoseExtentDeg of the one before).
  enum class Kind { kStrayLight, kUnsettled };
  std::optional<Joints> forced_at_deg;
  Kind forced_kind = Kind::kStrayLight;
};
// "stray_light", "unsettled"; the parse throws InputError naming the accepted words.
const char* grossKindName(GrossErrors::Kind kind);
GrossErrors::Kind parseGrossKind(const std::string& word);
constexpr double kGrossPoseExtentDeg = 5.0;
constexpr double kForcedPoseMatchDeg = 0.5;

// The realistic world's draws (randomWorld); docs/simulated-cell.md gives the evidence.
constexpr double kLinkLengthSigmaMm = 0.1;   // every a and d
constexpr double kLinkTwistSigmaDeg = 0.01;  // every alpha
constexpr double kDefaultGrossRate = 0.01;   // per pose, each kind
constexpr double kMassShareSpread = 0.25;    // each share of the arm's mass, relative
constexpr double kMassPositionSpread = 0.1;  // a mass's place along its link, of its length
constexpr double kPsdSeatSigmaMm = 0.005;    // the PSD on a kinematic base, per seating

// A place a session at several PSD placements had the detector moved to (placement 2, 3, ...):
// where the session planned it (its taught centre there; the orientation the session knows is
// psd_rotation_configured) and where it truly stands.
struct PsdPlacement {
  int placement = 2;
  Eigen::Vector3d planned_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
};

struct World {
  // The nominal robot: what the controller and the session believe.
  Robot robot;
  // Added to the controller's joint angles to get the true ones (deg).
  Joints true_offsets_deg{};
  // The true arm: its links' deviations from the nominal table, compliance and warming.
  std::array<DhError, kJointCount> dh_errors{};
  Compliance compliance;
  ThermalDrift thermal;
  // The beam in the flange frame: a point on it (mm) and its unit direction.
  Eigen::Vector3d laser_point_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d laser_direction = Eigen::Vector3d::UnitX();
  // The PSD frame in the base frame: x_base = psd_rotation * x_psd + psd_position_mm.
  Eigen::Vector3d psd_position_mm = Eigen::Vector3d(900, -50, 400);
  Eigen::Matrix3d psd_rotation = Eigen::Matrix3d::Identity();
  // What the technician gives the session: the PSD's orientation as configured (the mounting
  // drawing's) and its centre as taught by jogging.
  Eigen::Matrix3d psd_rotation_configured = Eigen::Matrix3d::Identity();
  Eigen::Vector3d psd_centre_taught_mm = Eigen::Vector3d(903, -53, 403);
  WorldNoise noise;
  GrossErrors gross;
  // A session at several placements: each further placement's truth (empty with one), and the
  // placement the PSD stands at now (1: psd_position_mm and psd_rotation). Not part of
  // worldHash: the same cell, its PSD moved.
  std::vector<PsdPlacement> placements;
  int active_placement = 1;
  // Where this session's seating put the PSD on its base, from psd_position_mm (placement 1
  // only; noise.psd_seat_mm). Not part of worldHash, not in a world file: a session's draw.
  Eigen::Vector3d psd_seated_mm = Eigen::Vector3d::Zero();
};

// The world with `change` (zerocal/sim/zero_change.h) applied to its true offsets. Throws
// InputError for a bad change.
void applyZeroChange(const ZeroChange& change, World* world);

// The world with its PSD (at placement 1: where a check or a restore measures) and its laser
// re-mounted (zerocal/sim/remount.h): the detector moved in the base frame and turned about its
// centre, the laser moved in the flange frame and its beam turned about its exit point; what the
// session is told (the configured orientation, the taught centre) stays. Throws InputError for a
// re-mount beyond the limits.
void applyRemount(const Remount& psd, const Remount& laser, World* world);

// Where the PSD truly stands when a session puts it at `placement` (2, 3, ...) planned at
// `planned_mm`: as far from the planned centre as the world's taught centre is from its PSD
// (|psd_centre_taught_mm - psd_position_mm|), and turned from psd_rotation_configured by as much
// as psd_rotation is, each in a direction drawn from `seed` and the placement number: the same
// kind and size of error as placement 1's, the same for the same seed, placement and plan.
PsdPlacement drawPlacement(const World& world, std::uint64_t seed, int placement,
                           const Eigen::Vector3d& planned_mm);

// Where the beam crosses the PSD plane (at the placement the PSD stands at).
struct BeamHit {
  PsdSpot spot;         // in the true PSD frame
  double range_mm = 0;  // from the laser point to the hit, along the beam
};

// The true beam for controller joints q_deg (true angles = q_deg + true offsets + extra_deg +
// gravity sag, extra_deg being e.g. the error of the current move) of the true arm at time_s
// (thermal state) meets the PSD plane; nullopt when the beam is parallel to the plane or points
// away from it. Allocates nothing.
std::optional<BeamHit> beamHit(const World& world, const Joints& q_deg,
                               const Joints& extra_deg = Joints{}, double time_s = 0);

// The true arm's joint deflection (deg) under gravity at controller joints q_deg.
Joints gravitySagDeg(const World& world, const Joints& q_deg);
// The true arm's lumped masses (Compliance's shares and positions; 1 kg in all) on the nominal
// arm's links.
std::vector<LumpedMass> trueMasses(const World& world);

// The flange pose of the true arm (links, offsets, sag, thermal state at time_s), in mm.
Eigen::Vector3d trueFlangePositionMm(const World& world, const Joints& q_deg, double time_s = 0);

// The gross errors in force at the arm's current pose (see GrossErrors).
struct GrossState {
  bool anchored = false;
  Joints anchor_deg{};  // the pose of the last draw
  Eigen::Vector2d stray_light_mm = Eigen::Vector2d::Zero();
  Joints unsettled_deg{};
  long draws = 0;            // poses drawn so far
  bool forced_done = false;  // GrossErrors::forced_at_deg has had its error
};

// Called after every move to q_deg: redraws `state` from `rng` when the arm left the last pose.
void updateGross(const GrossErrors& gross, const Joints& q_deg, std::mt19937_64& rng,
                 GrossState* state);

// A fingerprint of everything that makes a world (robot, offsets, the true arm, laser, PSD pose
// and what is known of it, noise, gross errors), as 16 hex digits: equal for the same seed or
// the same world file on every build of this code, so two processes can check that they
// simulate the same cell.
std::string worldHash(const World& world);

// Reads a world file (config/worlds/example.yaml):
//   robot: builtin                      # or a robot file, relative to the world file's folder
//   true_offsets_deg: [6 numbers]
//   laser: {point_mm: [x, y, z], direction: [x, y, z]}          # flange frame
//   psd: {position_mm: [x, y, z], rpy_deg: [roll, pitch, yaw]}  # base frame, R = Rz Ry Rx
//        optional: configured_rpy_deg (default rpy_deg), taught_centre_mm (default position
//        + (3, -3, 3))
//   noise: {repeatability_deg: 1.5e-3, psd_mm: 0.001, seed: 7}  # optional; seed: the
//        session noise's (WorldNoise::seed)
//   optional, each absent = none (the ideal arm):
//   dh_errors: {a_mm: [6], d_mm: [6], alpha_deg: [6]}
//   compliance: {joint2_sag_deg: x, joint3_sag_deg: x, mass_share: [3], mass_position: [2]}
//   thermal: {expansion_per_k: x, rise_k: x, time_constant_s: x}
//   gross_errors: {stray_light_rate: x, stray_light_mm: x, unsettled_rate: x, unsettled_deg: x,
//                  forced_at_deg: [6 numbers], forced_kind: stray_light | unsettled}
//   placements: [{placement: 2, planned_mm: [3], position_mm: [3], rpy_deg: [3]}, ...]  # truth
//        of a session at several placements; the world is read with the PSD at placement 1
// Throws ConfigError listing every problem found.
World loadWorld(const std::string& path);
World parseWorld(const std::string& yaml_text, const std::string& origin,
                 const std::string& base_dir = ".");
// The world as a world file, every number to 17 digits: the truth a simulated session ran on.
// parseWorld reads it back to the same world up to rounding (the PSD rotations go through
// roll-pitch-yaw). `robot_file` is what the file's robot key names.
std::string worldYaml(const World& world, const std::string& robot_file = "builtin");

enum class WorldKind {
  kRealistic,  // every imperfection of a real cell (docs/simulated-cell.md)
  kIdeal,      // the exact nominal arm, the PSD orientation known, no gross errors
};

// A random but plausible world, the same for the same seed: the built-in IRB1600, offsets
// uniform in +-1 deg, a laser near the flange x axis, the PSD facing up near (900, -50, 400) mm
// with a tilt of up to 10 deg, taught 3 mm off on each axis. kRealistic adds, from a second
// stream of the same seed, the arm's link errors, compliance and warming, the PSD's configured
// orientation a few degrees off, a taught centre a few mm off in a random direction and gross
// errors at their default rates; the offsets, laser and PSD pose are those of kIdeal.
World randomWorld(std::uint64_t seed, WorldKind kind = WorldKind::kRealistic);

}  // namespace zerocal
