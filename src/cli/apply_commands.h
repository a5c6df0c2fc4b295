// zerocal apply: a session's identified offsets turned into the controller's MOTOR_CALIB
// cal_offset values and written into a copy of a MOC.cfg from the controller's backup
// (docs/apply.md).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <ostream>
#include <string>

#include "control_commands.h"

namespace zerocal::cli {

struct ApplyArgs {
  std::string session_dir;
  std::string moc_file;
  std::string out_file;
  std::string robot;  // empty: the one in the session's configuration snapshot
  bool unconfirmed_transmission = false;
  // Online (no --moc): through zerocald, behind this confirmation; the connection options.
  bool confirm = false;
  ClientArgs client;
};

struct ApplyExperimentArgs {
  int worlds = 10;
  std::uint64_t seed0 = 1;
  int poses = 0;             // the command line sets the daemon's session.poses
  int wrong_sign_joint = 0;  // 2..5: that joint's transmission sign flipped in the configuration
  double required_deg = 0.003;
};

struct ApplyCommands {
  CLI::App* apply = nullptr;
  CLI::App* experiment = nullptr;  // experiment apply
  ApplyArgs args;
  ApplyExperimentArgs experiment_args;
  bool parsed() const { return apply->parsed() || (experiment && experiment->parsed()); }
};

// Registers `apply` and, when `app` has an `experiment` subcommand, `experiment apply`;
// `commands` must outlive the parse.
void addApplyCommands(CLI::App& app, ApplyCommands& commands);

// The parsed one of them; its exit code.
int runApplyCommands(const ApplyCommands& commands, std::ostream& out, std::ostream& err);

// With --moc, the file apply below; without, the online apply through zerocald (runClient's
// codes: 0 applied and verified, 8 verified wrong and rolled back, 3 stopped, 2 refused or no
// --confirm).
// Returns the exit code: 0 written; 2 refused (bad input, a file not fully understood, an
// unconfirmed transmission); 3 the session's solve did not converge; 4 an offset of joints 2..5
// is not identifiable. Never throws; messages go to err.
int runApply(const ApplyArgs& args, std::ostream& out, std::ostream& err);

// 0 when the experiment's requirements hold, 7 when not, 1 when a calibration failed.
int runApplyExperiment(const ApplyExperimentArgs& args, std::ostream& out, std::ostream& err);

}  // namespace zerocal::cli
