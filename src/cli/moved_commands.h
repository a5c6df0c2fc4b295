// The commands that moved from zerocal to zerocal-lab with the engine, the PSD chain, the report
// and the experiments (docs/cli.md): for a release, their old names stay here and say where they
// went, so that a script or a habit gets a clear answer instead of "unknown command". They do not
// run the new program: this client has no engine, and a technician's terminal may have no
// zerocal-lab installed.
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>
#include <string>
#include <vector>

namespace zerocal::cli {

// The exit code of a moved command: usage, as for an unknown one.
constexpr int kMovedCommand = 2;

struct MovedCommands {
  std::vector<CLI::App*> apps;  // solve, simulate, sensitivity, experiment, psd..., report
};

// Registers the old names, each taking any arguments; `moved` must outlive the parse.
void addMovedCommands(CLI::App& app, MovedCommands& moved);

// When one of them was given: the message naming `zerocal-lab` with the same arguments, and
// kMovedCommand; -1 when none was.
int runMovedCommands(const MovedCommands& moved, std::ostream& err);

// The message for `command` (as the user typed it) now run as `zerocal-lab <lab_command_line>`;
// returns kMovedCommand.
int refuseMovedCommand(const std::string& command, const std::string& lab_command_line,
                       std::ostream& err);

// The words as a shell line to copy: a word with a space or a quote in it, or none, is quoted.
std::string commandLine(const std::vector<std::string>& words);

}  // namespace zerocal::cli
