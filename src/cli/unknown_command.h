// An unknown first word refused with the nearest command, for zerocal and zerocal-lab alike.
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>
#include <set>
#include <string>
#include <vector>

namespace zerocal::cli {

// When `word` is meant as a command of `app` and is none: says so on `err`, with the nearest
// command if exactly one is close (`sovle` -> solve), and returns true. A command in `acting`
// (one that moves the robot or writes to its controller) is never offered for a word that a
// command outside it is as near or nearer to, or that begins one (`stat` -> status, not start).
// The same for a long option of `app` itself (`--verison` -> --version); other options are
// CLI11's to judge.
bool refuseUnknownCommand(const CLI::App& app, const std::string& word, std::ostream& err,
                          const std::set<std::string>& acting = {});

// `program help [COMMAND]`: when `words` (the command line after the program's name) asks for
// it, prints the program's help or that command's on `out` and returns 0; an unknown COMMAND is
// refused as above (2). -1 when the words are not a help request.
int answerHelp(const CLI::App& app, const std::vector<std::string>& words, std::ostream& out,
               std::ostream& err);

}  // namespace zerocal::cli
