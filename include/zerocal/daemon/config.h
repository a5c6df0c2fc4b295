// The configuration of zerocald: one struct per section, filled in layers (compiled defaults, the
// main file, every *.yaml of the drop-in folder in lexical order, then command-line overrides
// `section.key=value`) and validated once, reporting every problem at once. docs/configuration.md
// describes every key; config/zerocald.yaml is the commented example.
//
// Units are in the key names and the member names: _mm millimetres, _um micrometres, _deg
// degrees, _s seconds, _ms milliseconds (std::chrono::milliseconds), _v volts, _hz hertz.
// Relative paths written in a file are resolved against that file's folder, those on the command
// line against the working directory.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/cell/kinds.h"
#include "zerocal/control/server_options.h"
#include "zerocal/paths.h"
#include "zerocal/psd/psd_config.h"
#include "zerocal/service/plan_kind.h"
#include "zerocal/servo/servo.h"
#include "zerocal/web/web_options.h"

namespace zerocal {

enum class BackendKind { kHardware, kSim };

struct BackendConfig {
  BackendKind kind = BackendKind::kHardware;
  // Simulated cell: a world file, or a seed from which a random world is drawn; not both. With
  // neither, the seed 1 world. Each session draws its own noise on it (sim::SessionNoise).
  std::string sim_world;
  std::optional<std::uint64_t> sim_seed;
  // A seed's world: realistic (the arm's geometry, compliance and warming, the PSD's orientation
  // and centre as known, gross errors; docs/simulated-cell.md) or ideal (exact, for tests).
  bool sim_ideal_world = false;
  // A motor replaced: joint sim_zero_change_joint's (2..5; 0 none) true zero moved by
  // sim_zero_change_deg (non-zero, within +-kMaxZeroChangeDeg = 2 deg) on top of the world's
  // offsets (sim::ZeroChange).
  int sim_zero_change_joint = 0;
  double sim_zero_change_deg = 0;
  // The PSD and the laser taken off and mounted again (sim::Remount): the detector moved in the
  // base frame (mm) and turned about its centre (roll, pitch, yaw deg), the laser moved in the
  // flange frame and its beam turned; each component within +-kMaxRemountMm, +-kMaxRemountDeg.
  std::array<double, 3> sim_psd_moved_mm{};
  std::array<double, 3> sim_psd_turned_deg{};
  std::array<double, 3> sim_laser_moved_mm{};
  std::array<double, 3> sim_laser_turned_deg{};
  // The arm's thermal state: the simulated controller's time when the daemon starts it (s), as
  // if the robot had been working that long (World::thermal warms with the controller's time);
  // 0 a cold arm, 0..kMaxWarmS (a week). Two daemons with different values play a robot measured
  // warm and cold.
  double sim_warm_s = 0;
  // Realistic seeded worlds: the chance per pose of each kind of gross error.
  double sim_gross_rate = 0.01;
  // Wall seconds per simulated second of a move: 0 as fast as the computer goes, 1 real time,
  // 0.1 ten times faster (to watch a session on the simulated cell).
  double sim_pace = 0.0;
  // The in-process simulated controller's fixed cost per move (s): the request and reply and the
  // motion planner's start-up that a real IRC5 pays for every move (docs/simulated-cell.md).
  double sim_move_overhead_s = 0.3;
  // An external zerocal-sim process instead of the in-process one: both set, or neither.
  std::string sim_host;
  std::uint16_t sim_port = 0;
};

// The controller section: which kind of controller (controller.kind: its section, its link and
// its motion model, zerocal/cell/controller_kind.h), which robot, and the servo's step ceiling.
// Every known kind has its own section (controller.<kind>), which that kind declares and checks;
// the configuration uses the one `kind` names.
struct ControllerConfig {
  std::string kind = kinds::controllerKinds().front().name;
  std::string robot = "builtin";  // robot file, or the compiled-in IRB 1600-10/1.45
  // Ceiling of servo.max_step_deg (deg). Not a step limit of the link: the moves between planned
  // poses span up to ~240 deg of wrist rotation by design, and are checked against the limits
  // and previewed instead.
  double max_step_deg = 10.0;
  settings::KindSections<ControllerSettings> sections = kinds::controllerSections();

  // The section `kind` names. Throws ConfigError when no kind has that name (a validated
  // configuration always has it).
  const ControllerSettings& section() const;
};

// The daq section: which board reads the PSD (daq.kind: its section and its readout,
// zerocal/cell/daq_kind.h), and the PSD chain's vendor-free part (its light threshold and map).
// Every known board has its own section (daq.<kind>).
struct DaqConfig {
  std::string kind = kinds::daqKinds().front().name;
  psd::PsdConfig psd;  // daq.sum_threshold_v, daq.map_file
  settings::KindSections<DaqSettings> boards = kinds::daqSections();

  // The board `kind` names. Throws ConfigError when no board has that name.
  const DaqSettings& board() const;
};

struct SessionConfig {
  PlanKind plan = PlanKind::kOptimal;
  std::string plan_file;  // a joint-set file; required by plan: file, refused otherwise
  int poses = 16;         // with several placements: at each
  // PSD placements of a session: 1, or 2..kMaxDefaultPlacements (the first at target_mm, the
  // others spread around it; the technician moves the PSD between them, docs/daemon.md).
  int placements = 1;
  std::array<double, 3> target_mm{900.0, -50.0, 400.0};  // nominal PSD centre, robot base frame
  // The PSD's orientation in the base frame: roll, pitch, yaw (fixed x, y, z); 0 0 0 faces up.
  std::array<double, 3> psd_rpy_deg{0.0, 0.0, 0.0};
  // The measurement noise of every pose (zerocal/calib/cell_model.h MissNoise): each joint's
  // repeatability (one sigma per move, deg), seen at the PSD through the pose's joint Jacobian,
  // plus the PSD's reading noise (mm per axis). The IRB 1600's position repeatability RP 0.02 mm
  // split into equal joint errors gives 1.5e-3 deg (docs/simulated-cell.md). 0: every pose has
  // noise_mm instead (the isotropic model, a user's explicit choice).
  double joint_repeatability_deg = 1.5e-3;
  double psd_noise_mm = 0.001;
  // The isotropic measurement sigma at the PSD (mm): every pose's when joint_repeatability_deg
  // is 0; otherwise only a plan file's prediction without a cell uses it.
  double noise_mm = 0.020;
  // The accuracy the calibration is for: an offset known only worse than this (one sigma) is
  // not identified, and the result not usable (SolveOptions::required_accuracy_deg).
  double required_accuracy_deg = 0.01;
  // How closely the PSD's base puts it back where it stood (one sigma per axis, mm, per seating):
  // a check or a restore counts it (ChangeOptions::psd_base_repeatability_mm). The default is a
  // kinematic base's, as the simulated cell's (docs/configuration.md).
  double psd_base_repeatability_mm = 0.005;
  std::string data_dir = "/var/lib/zerocal/sessions";  // one folder per session (journal.h)
};

enum class LogLevel { kTrace, kDebug, kInfo, kWarn, kError, kCritical, kOff };

struct LoggingConfig {
  LogLevel level = LogLevel::kInfo;
  std::string directory;  // empty: stderr only (the systemd journal); else also zerocald.log there
};

struct DaemonConfig {
  BackendConfig backend;
  ControllerConfig controller;
  DaqConfig daq;
  servo::ServoOptions servo;  // the servo section is the servo's own options (servo.h)
  SessionConfig session;
  control::ServerOptions control;  // the control section is the server's own options
  web::WebOptions web;             // the web section is the web terminal's own options
  LoggingConfig logging;
};

// Where the layers come from. A missing main file is fine when it is the default one and an error
// when it was named explicitly; the same holds for the drop-in folder.
struct ConfigSources {
  std::string config_path = kDefaultConfigPath;
  bool config_path_explicit = false;
  std::string drop_in_dir = kDefaultDropInDir;
  bool drop_in_dir_explicit = false;
  std::vector<std::string> overrides;  // "section.key=value", value in YAML syntax
};

// Builds the configuration from all layers and validates it. Throws ConfigError carrying every
// problem found in every layer (unreadable or malformed files, unknown keys, wrong types,
// out-of-range values, inconsistent combinations), each naming its file and line, or the command
// line, and the key path.
DaemonConfig loadDaemonConfig(const ConfigSources& sources);

// Incremental building, for tests and for the daemon's reload: each call layers one source on top
// of `config` and adds its problems to `problems`; `origins` records where every key was last set
// ("file:line"), so that validation messages can point at it.
using ConfigOrigins = std::map<std::string, std::string>;
void applyConfigYaml(DaemonConfig& config, const std::string& yaml_text, const std::string& origin,
                     const std::string& base_dir, ConfigOrigins& origins,
                     std::vector<std::string>& problems);
void applyConfigOverride(DaemonConfig& config, const std::string& assignment,
                         ConfigOrigins& origins, std::vector<std::string>& problems);

// Range and consistency checks of a complete configuration, including that referenced files
// exist. Returns the problems (empty when valid); never throws.
std::vector<std::string> validateDaemonConfig(const DaemonConfig& config,
                                              const ConfigOrigins& origins = {});

// Every key with its value, nested by section, as written in a file; for session.json snapshots.
nlohmann::json configToJson(const DaemonConfig& config);

// Every key path the files accept ("servo.tolerance_um", "daq.usb-1408fs.channels.x.number",
// ...), every kind's included.
std::vector<std::string> configKeys();

// The daq section alone, for `zerocal-lab psd`: the defaults, then the `daq:` section of the file
// at `path` (zerocald's own configuration file, or any file with a daq: section; its other sections
// are zerocald's to check), validated as zerocald validates it. Throws ConfigError carrying every
// problem; a file with the `psd:` section of earlier versions is refused with the renamed keys.
DaqConfig loadDaqSection(const std::string& path);

std::string logLevelName(LogLevel level);

// Whether zerocald serves the web terminal: web.enabled, or with `auto` (the default) on the
// simulated cell only.
bool webEnabled(const DaemonConfig& config);

}  // namespace zerocal
