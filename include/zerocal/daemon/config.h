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

#include "zerocal/paths.h"
#include "zerocal/psd/psd.h"
#include "zerocal/service/plan_kind.h"
#include "zerocal/servo/servo.h"

namespace zerocal {

enum class BackendKind { kHardware, kSim };

struct BackendConfig {
  BackendKind kind = BackendKind::kHardware;
  // Simulated cell: a world file, or a seed from which a random world is drawn; not both. With
  // neither, the seed 1 world.
  std::string sim_world;
  std::optional<std::uint64_t> sim_seed;
  // A seed's world: realistic (the arm's geometry, compliance and warming, the PSD's orientation
  // and centre as known, gross errors; docs/simulated-cell.md) or ideal (exact, for tests).
  bool sim_ideal_world = false;
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

// Which controller the cell has, hence which link the cell factory makes
// (zerocal/service/cell_factory.h): ABB's IRC5 through zerocal's RAPID socket server.
enum class ControllerKind { kIrc5 };

// The controller link (for the IRC5 mapped onto Irc5Options by the cell factory).
struct ControllerConfig {
  ControllerKind kind = ControllerKind::kIrc5;
  std::string robot = "builtin";  // robot file, or the compiled-in IRB 1600-10/1.45
  std::string host = "192.168.125.1";
  std::uint16_t port = 5000;
  std::chrono::milliseconds connect_timeout{2000};
  std::chrono::milliseconds request_timeout{1000};
  double move_timeout_factor = 2.0;  // a move's deadline: estimated duration * factor + margin
  std::chrono::milliseconds move_timeout_margin{2000};
  double speed_tcp_mm_s = 250.0;  // calibration moves are short and the cell is closed
  double speed_ori_deg_s = 100.0;
  double limit_margin_deg = 1.0;  // joint targets closer than this to a limit are refused
  double max_step_deg = 10.0;     // largest joint step of any one move
  int reconnect_attempts = 5;
};

// Which acquisition board reads the PSD, hence which readout the cell factory makes: the
// Measurement Computing USB-1408FS through zerocal's libusb driver.
enum class DaqKind { kUsb1408fs };

struct DaqConfig {
  DaqKind kind = DaqKind::kUsb1408fs;
  std::string serial;  // USB serial-number string; empty = the first USB-1408FS found
  psd::PsdChannels channels;
  double scan_rate_hz = 1000.0;   // scans per second (each scan converts x, y and sum once)
  int samples_per_reading = 100;  // scans averaged into one reading
  double sum_threshold_v = 0.5;   // SUM below this: no spot on the detector
  std::string map_file;  // the PSD's volts-to-mm map (zerocal psd-map); required by hardware
};

struct SessionConfig {
  PlanKind plan = PlanKind::kOptimal;
  std::string plan_file;  // a joint-set file; required by plan: file, refused otherwise
  int poses = 8;
  std::array<double, 3> target_mm{900.0, -50.0, 400.0};  // nominal PSD centre, robot base frame
  // The PSD's orientation in the base frame: roll, pitch, yaw (fixed x, y, z); 0 0 0 faces up.
  std::array<double, 3> psd_rpy_deg{0.0, 0.0, 0.0};
  double noise_mm = 0.020;  // measurement sigma: the robot's repeatability seen at the PSD
  // The accuracy the calibration is for: an offset known only worse than this (one sigma) is
  // not identified, and the result not usable (SolveOptions::required_accuracy_deg).
  double required_accuracy_deg = 0.01;
  // One-sigma tolerances of the robot's link lengths and twists, which the method does not
  // identify: their effect is added to every offset's sigma (SolveOptions::model_length_mm).
  double model_length_mm = 0.1;
  double model_angle_deg = 0.01;
  std::string data_dir = "/var/lib/zerocal/sessions";  // one folder per session (journal.h)
};

struct ControlConfig {
  std::string bind_address = "127.0.0.1";
  std::uint16_t port = 7450;
  std::string token_file;  // required to serve the port; checked when bind_address is not loopback
  int max_clients = 64;    // connections at once; more are refused politely
  int max_line_bytes = 65536;     // longest request line; a longer one is refused and closed
  double idle_timeout_s = 600;    // a connection that sends no request this long is closed
  double write_timeout_s = 30;    // a client whose write is stuck this long is dropped
  int max_queued_kib = 1024;      // output queued for one client before it is dropped
  int max_auth_failures = 3;      // failed auth attempts before a connection is closed
  int max_clients_per_peer = 16;  // connections from one address at once
  double auth_timeout_s = 10;     // a connection not authenticated this long is closed
  // Plan files named in `start`/`plan` requests are file names in this folder; empty: none.
  std::string plan_dir = "/var/lib/zerocal/plans";
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
  ControlConfig control;
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

// Every key path the files accept ("servo.tolerance_um", "daq.channels.x.number", ...).
std::vector<std::string> configKeys();

std::string logLevelName(LogLevel level);

}  // namespace zerocal
