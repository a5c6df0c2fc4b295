// zerocal apply --confirm: a session's offsets applied online through zerocald (backed up,
// written, the controller restarted, verified by measurement, rolled back when wrong;
// docs/apply.md). The MOC.cfg file apply is zerocal-lab's (`zerocal-lab apply DIR --moc ...`).
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>
#include <string>
#include <vector>

#include "control_commands.h"

namespace zerocal::cli {

struct ApplyArgs {
  std::string session;   // the session id
  bool confirm = false;  // the technician confirmed writing the robot's calibration
  // The file apply's options, which is zerocal-lab's now: given, the message names it.
  std::string moc_file, out_file, robot;
  bool unconfirmed_transmission = false;
  ClientArgs client;  // the connection options
};

struct ApplyCommands {
  CLI::App* apply = nullptr;
  ApplyArgs args;
  bool parsed() const { return apply->parsed(); }
};

// Registers `apply`; `commands` must outlive the parse.
void addApplyCommands(CLI::App& app, ApplyCommands& commands);

// runClient's codes: 0 applied and verified, 8 verified wrong and rolled back, 3 stopped, 2
// refused, without --confirm, or with --moc (the file apply: the message names zerocal-lab with
// `words`, the command line after the program's name).
int runApplyCommands(const ApplyCommands& commands, const std::vector<std::string>& words,
                     std::ostream& out, std::ostream& err);

}  // namespace zerocal::cli
