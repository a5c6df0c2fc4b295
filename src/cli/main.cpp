// zerocal: the technician's client of zerocald's control port (start, status, watch, abort,
// resume, continue, sessions, result, plan, apply --confirm, verify, acknowledge, version). It
// links no engine, driver or simulator (tests/cli checks its link); the engine's commands, the PSD
// chain, the report and the experiments are zerocal-lab's (src/lab), and their old names here say
// so (moved_commands.h).
// Exit codes (docs/cli.md, control_commands.h): 0 done; 1 unexpected failure; 2 usage, a refusal,
// or a command that moved to zerocal-lab; 3 the watched session was aborted or faulted; 4 not
// identifiable; 5 cannot connect; 6 token refused or unusable; 8 an apply verified wrong.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <iterator>
#include <set>
#include <string>
#include <vector>

#include "apply_commands.h"
#include "control_commands.h"
#include "moved_commands.h"
#include "unknown_command.h"
#include "zerocal/calib/pose_count.h"

namespace zerocal::cli {
namespace {

// The options of a plan made with the engine (`zerocal-lab plan --robot ...`): given here, the
// plan is refused with the message naming that program, before anything is sent.
const char* const kLocalPlanOptions[] = {
    "--standoff",     "--margin", "--max-incidence",   "--sweep",       "--psd-normal",
    "--joint1-fixed", "--out",    "--laser-direction", "--laser-point", "--placement"};

struct PlanCommand {
  CLI::App* plan = nullptr;
  ClientArgs args;
};

void addPlanCommand(CLI::App& app, PlanCommand& command) {
  ClientArgs& a = command.args;
  auto* c = command.plan = app.add_subcommand(
      "plan",
      "plan poses on zerocald and predict their uncertainty, moving nothing (a plan made here "
      "with a robot file is zerocal-lab plan --robot)");
  addConnectionOptions(c, a);
  c->add_option("--pattern", a.pattern, "I, II, mixed or optimal (default the daemon's)");
  c->add_option("--poses", a.poses, "number of poses (default the daemon's)");
  c->add_option("--target", a.target, "nominal target (PSD centre) in the base frame, mm")
      ->expected(3);
  c->add_option("--noise", a.noise_mm,
                "measurement sigma in mm for the prediction (default the daemon's "
                "session.noise_mm)");
  c->add_option("--placements", a.placements,
                "PSD placements of the session, --poses at each (default the daemon's)")
      ->check(CLI::Range(1, kMaxDefaultPlacements));
  c->add_flag("--json", a.json, "print one JSON object instead of text");
  c->allow_extras();  // the local plan's options: refused by name below
}

// `words`: the command line after the program's name, for the message naming zerocal-lab.
int runPlanCommand(const PlanCommand& command, const std::vector<std::string>& words,
                   std::ostream& err) {
  // The local plan's options, left over by this parse: --robot anywhere makes it the lab's plan.
  std::vector<std::string> names;
  for (const std::string& arg : command.plan->remaining())
    if (arg.rfind("--", 0) == 0) names.push_back(arg.substr(0, arg.find('=')));
  std::string local;
  for (const std::string& name : names) {
    const bool known = std::find(std::begin(kLocalPlanOptions), std::end(kLocalPlanOptions),
                                 name) != std::end(kLocalPlanOptions);
    if (name == "--robot" || (known && local.empty())) local = name;
    if (!known && name != "--robot") {
      err << "zerocal: plan: unknown option " << name << " (zerocal plan --help)\n";
      return kClientBadRequest;
    }
  }
  if (local == "--robot") return refuseMovedCommand("plan --robot", commandLine(words), err);
  if (!local.empty()) {
    err << "zerocal: plan " << local
        << " needs --robot (a plan made here, with the engine: zerocal-lab plan --robot FILE "
           "...)\n";
    return kClientBadRequest;
  }
  if (!command.plan->remaining().empty()) {
    err << "zerocal: plan takes no arguments: " << commandLine(command.plan->remaining()) << "\n";
    return kClientBadRequest;
  }
  ClientArgs args = command.args;
  args.command = "plan";
  return runClient(args, std::cout, err, isatty(1));
}

}  // namespace
}  // namespace zerocal::cli

int main(int argc, char** argv) {
  using namespace zerocal::cli;
  CLI::App app{
      "zerocal: the technician's client of zerocald, the cell daemon that calibrates the joint "
      "zero offsets delta2..delta5 of a 6R robot with a laser and a PSD. The engine's commands, "
      "the PSD chain, the report and the experiments are zerocal-lab's.",
      "zerocal"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "zerocal " + std::string(PROJECT_VERSION));

  ClientCommands client_cmds;
  addClientCommands(app, client_cmds);
  PlanCommand plan_cmd;
  addPlanCommand(app, plan_cmd);
  ApplyCommands apply_cmds;
  addApplyCommands(app, apply_cmds);
  MovedCommands moved;
  addMovedCommands(app, moved);

  const std::vector<std::string> words(argv + 1, argv + argc);
  if (const int rc = answerHelp(app, words, std::cout, std::cerr); rc >= 0) return rc;
  // The commands that move the robot or write to its controller: never offered for a typo that
  // a read-only command is as near to.
  const std::set<std::string> acting = {"start", "resume", "continue",
                                        "apply", "verify", "acknowledge"};
  if (argc > 1 && refuseUnknownCommand(app, argv[1], std::cerr, acting)) return kClientBadRequest;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version arrive here too, with exit code 0; every real usage error is bad
    // input, so scripts see the same code as for a bad file.
    return app.exit(e) == 0 ? kClientOk : kClientBadRequest;
  }

  if (const int rc = runMovedCommands(moved, std::cerr); rc >= 0) return rc;
  for (auto* c : client_cmds.apps)
    if (c->parsed()) return runClient(client_cmds.args, std::cout, std::cerr, isatty(1));
  if (apply_cmds.parsed()) return runApplyCommands(apply_cmds, words, std::cout, std::cerr);
  if (plan_cmd.plan->parsed()) return runPlanCommand(plan_cmd, words, std::cerr);
  return kClientFailure;
}
