// Who a login speaks for (docs/protocol.md, "Roles"), on the TCP port and in the web terminal
// alike. The engineer's token (control.token_file) may do everything. The operator's
// (control.operator_token_file, when configured) may watch, read, check the zeros against the
// robot's reference and abort: nothing that writes into the controller or calibrates.
#pragma once

#include <string>

#include "zerocal/control/server_options.h"
#include "zerocal/results/session_file.h"

namespace zerocal::control {

enum class Role { kNone, kOperator, kEngineer };
const char* roleName(Role role);  // "none", "operator", "engineer"

// The role whose token `given` is (compared in constant time); kNone for neither.
Role roleOfToken(const ServerOptions& options, const std::string& given);

// Why `role` may not send `cmd`, or "" when it may. A start is judged by its kind instead.
std::string forbiddenCommand(Role role, const std::string& cmd);
// Why `role` may not start a session of `kind`, or "" when it may.
std::string forbiddenStart(Role role, SessionKind kind);

}  // namespace zerocal::control
