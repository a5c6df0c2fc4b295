// The client subcommands of zerocal, which drive zerocald's control port (docs/protocol.md):
// start, status, watch, abort, resume, continue, sessions, result, verify, acknowledge, robots,
// history, version; main.cpp adds plan and apply, which run through runClient too.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace zerocal::cli {

// Exit codes of the client commands, beside those of zerocal-lab's (0, 1, 2, 4 mean the same
// there): docs/cli.md.
enum ClientExit {
  kClientOk = 0,
  kClientFailure = 1,
  kClientBadRequest = 2,     // usage, or the daemon refused the request (busy, not_found, ...)
  kClientSessionFailed = 3,  // the watched session ended aborted or faulted
  kClientNotIdentifiable = 4,
  kClientCannotConnect = 5,  // no daemon at --host:--port, or the connection broke
  kClientAuthRefused = 6,    // the token file cannot be used, or the daemon refused the token
  // result, watch: the verdict is not usable; apply: the verification found the new values wrong
  // and the backup was restored; verify: an offset left is beyond its bound.
  kClientVerificationFailed = 8,
  kClientNotUsable = 8,
  // result, watch: a check found a zero moved, or could not tell (changed, marginal).
  kClientCheckNotPassed = 9,
};

struct ClientArgs {
  std::string command;  // start, status, watch, abort, resume, sessions, result, version, plan
  std::string host = "127.0.0.1";
  std::uint16_t port = 7450;
  std::string token_file;  // empty: $ZEROCAL_TOKEN_FILE, else /etc/zerocal/token
  bool json = false;
  bool watch = false;    // start, resume: then watch the session
  bool confirm = false;  // apply: the technician confirmed writing the robot's calibration
  std::string session;   // resume, result, apply, verify: a session id (default the latest)
  int skip_pose = 0;     // resume: the next pose, to skip (1-based; 0: none)
  std::string pattern;   // start, plan: optimal, I, II, mixed, file (default the daemon's)
  std::optional<int> poses;
  std::string plan_file;
  std::vector<double> target;  // empty or X Y Z in mm
  std::optional<double> noise_mm;
  std::optional<int> placements;    // start, plan: PSD placements (default the daemon's)
  bool even_if_not_usable = false;  // start: a plan predicted short of the required accuracy
  std::string kind;            // start: calibrate, reference, check or restore (default: calibrate)
  std::string reference;       // start: the reference a check or restore compares with
  std::vector<double> centre;  // continue: empty or the placement's taught centre X Y Z, mm
  double timeout_s = 10;       // per request; `plan` takes its own time on the daemon
  int limit = 20;              // sessions: the newest this many
  bool all = false;            // sessions: every one, page after page
  std::string serial;          // history: the robot (default the record's only one)
  std::string robot_type;      // history: its type, when two robots share the serial
  bool csv = false;            // history: CSV instead of text
};

struct ClientCommands {
  std::vector<CLI::App*> apps;  // start, status, watch, abort, resume, sessions, result
  ClientArgs args;
};

// Registers the subcommands (all but plan and apply, which main.cpp registers); `commands` must
// outlive the parse.
void addClientCommands(CLI::App& app, ClientCommands& commands);
// --host, --port, --token-file on one subcommand.
void addConnectionOptions(CLI::App* command, ClientArgs& args);

std::string defaultTokenFile();

// Runs args.command against the daemon. `tty`: the live display redraws one line. Never throws;
// every failure is a message on `err` and an exit code.
int runClient(const ClientArgs& args, std::ostream& out, std::ostream& err, bool tty);

}  // namespace zerocal::cli
