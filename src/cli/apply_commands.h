// zerocal apply: a session's identified offsets turned into the controller's MOTOR_CALIB
// cal_offset values and written into a copy of a MOC.cfg from the controller's backup
// (docs/apply.md).
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>
#include <string>

namespace zerocal::cli {

struct ApplyArgs {
  std::string session_dir;
  std::string moc_file;
  std::string out_file;
  std::string robot;  // empty: the one in the session's configuration snapshot
  bool unconfirmed_transmission = false;
};

struct ApplyCommands {
  CLI::App* apply = nullptr;
  ApplyArgs args;
};

// Registers `apply`; `commands` must outlive the parse.
void addApplyCommands(CLI::App& app, ApplyCommands& commands);

// Returns the exit code: 0 written; 2 refused (bad input, a file not fully understood, an
// unconfirmed transmission); 3 the session's solve did not converge; 4 an offset of joints 2..5
// is not identifiable. Never throws; messages go to err.
int runApply(const ApplyArgs& args, std::ostream& out, std::ostream& err);

}  // namespace zerocal::cli
