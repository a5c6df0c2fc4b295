// zerocal-lab apply: a session's identified offsets turned into the controller's MOTOR_CALIB
// cal_offset values and written into a copy of a MOC.cfg from the controller's backup
// (docs/apply.md). The online apply through zerocald is the technician's `zerocal apply --confirm`.
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>
#include <string>

namespace zerocal::lab {

struct ApplyFileArgs {
  std::string session_dir;
  std::string moc_file;
  std::string out_file;
  std::string robot;  // empty: the one in the session's configuration snapshot
  bool unconfirmed_transmission = false;
};

struct ApplyFileCommand {
  CLI::App* apply = nullptr;
  ApplyFileArgs args;
};

// Registers `apply`; `command` must outlive the parse.
void addApplyFileCommand(CLI::App& app, ApplyFileCommand& command);

// Runs it when parsed (2 without --moc and --out) and returns runApplyFile's code, or -1 when it
// was not parsed.
int runApplyFileCommand(const ApplyFileCommand& command, std::ostream& out, std::ostream& err);

// Returns the exit code: 0 written; 2 refused (bad input, a file not fully understood, an
// unconfirmed transmission); 3 the session's solve did not converge; 4 an offset of joints 2..5
// is not identifiable. Never throws; messages go to err.
int runApplyFile(const ApplyFileArgs& args, std::ostream& out, std::ostream& err);

}  // namespace zerocal::lab
