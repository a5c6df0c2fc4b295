// An unknown first word refused with the nearest command, for zerocal and zerocal-lab alike.
#pragma once

#include <CLI/CLI.hpp>
#include <ostream>
#include <string>

namespace zerocal::cli {

// When `word` is meant as a command of `app` and is none: says so on `err`, with the nearest
// command if one is close (`sovle` -> solve), and returns true. Options (-x) are CLI11's to judge.
bool refuseUnknownCommand(const CLI::App& app, const std::string& word, std::ostream& err);

}  // namespace zerocal::cli
