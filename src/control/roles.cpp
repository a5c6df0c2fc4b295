#include "zerocal/control/roles.h"

#include "zerocal/control/token.h"

namespace zerocal::control {

const char* roleName(Role role) {
  switch (role) {
    case Role::kOperator:
      return "operator";
    case Role::kEngineer:
      return "engineer";
    case Role::kNone:
      break;
  }
  return "none";
}

Role roleOfToken(const ServerOptions& options, const std::string& given) {
  // Both compared, whichever matches: the time does not tell which token was tried.
  const bool engineer = tokensEqual(given, options.token);
  const bool op = !options.operator_token.empty() && tokensEqual(given, options.operator_token);
  return engineer ? Role::kEngineer : op ? Role::kOperator : Role::kNone;
}

namespace {

std::string engineers(const std::string& what) {
  return "'" + what +
         "' is an engineer's: the operator's login checks the zeros (start --kind check), "
         "watches and aborts; log in with the engineer's token (control.token_file)";
}

}  // namespace

std::string forbiddenCommand(Role role, const std::string& cmd) {
  const bool engineer_only = cmd == "apply" || cmd == "verify" || cmd == "acknowledge" ||
                             cmd == "resume" || cmd == "continue";
  return role == Role::kOperator && engineer_only ? engineers(cmd) : "";
}

std::string forbiddenStart(Role role, SessionKind kind) {
  return role == Role::kOperator && kind != SessionKind::kCheck
             ? engineers(std::string("start --kind ") + sessionKindName(kind))
             : "";
}

}  // namespace zerocal::control
