// zerocal-lab report: (re)writes summary.txt and report.html of a session folder and prints the
// summary, or with --json the paths and the offsets.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

namespace zerocal::lab {

struct ReportCommand {
  CLI::App* report = nullptr;
  std::string session_dir;
  bool json = false;
};

void addReportCommand(CLI::App& app, ReportCommand& command);

// Runs it when parsed and returns its exit code, or -1 when it was not parsed. A session folder
// that cannot be read throws report::ReportError / JournalError / FileError (main maps them).
int runReportCommand(const ReportCommand& command);

}  // namespace zerocal::lab
