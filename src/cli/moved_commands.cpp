#include "moved_commands.h"

namespace zerocal::cli {

void addMovedCommands(CLI::App& app, MovedCommands& moved) {
  for (const char* name : {"solve", "simulate", "sensitivity", "experiment", "psd-sweep", "psd-map",
                           "psd", "report"}) {
    auto* c = app.add_subcommand(name, std::string("now zerocal-lab ") + name);
    c->group("Moved to zerocal-lab (the engineer's program)");
    c->prefix_command();  // every argument, options and --help included, is the message's
    c->set_help_flag();
    moved.apps.push_back(c);
  }
}

int runMovedCommands(const MovedCommands& moved, std::ostream& err) {
  for (const CLI::App* c : moved.apps) {
    if (!c->parsed()) continue;
    std::vector<std::string> words{c->get_name()};
    for (const std::string& arg : c->remaining()) words.push_back(arg);
    return refuseMovedCommand(c->get_name(), commandLine(words), err);
  }
  return -1;
}

int refuseMovedCommand(const std::string& command, const std::string& lab_command_line,
                       std::ostream& err) {
  err << "zerocal: '" << command
      << "' has moved to zerocal-lab, the engineer's program (zerocal is the technician's client "
         "of zerocald); run\n  zerocal-lab "
      << lab_command_line << "\n";
  return kMovedCommand;
}

std::string commandLine(const std::vector<std::string>& words) {
  std::string line;
  for (const std::string& word : words) {
    if (!line.empty()) line += ' ';
    if (!word.empty() && word.find_first_of(" \t'\"\\$`") == std::string::npos) {
      line += word;
      continue;
    }
    line += '\'';
    for (const char c : word) line += c == '\'' ? std::string("'\\''") : std::string(1, c);
    line += '\'';
  }
  return line;
}

}  // namespace zerocal::cli
