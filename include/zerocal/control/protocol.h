// The control port's JSON-lines protocol (docs/protocol.md): its version, error codes, and the
// conversions between protocol objects and the service's types, shared by the server and the
// client.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/service/session_manager.h"

namespace zerocal::control {

// Raised when a change would break an existing client: a removed command or member, a changed
// meaning. New commands, members and events do not change it.
inline constexpr int kProtocolVersion = 1;
inline constexpr std::uint16_t kDefaultPort = 7450;

// Error codes of a response {"ok": false, "error": {"code": ..., "message": ...}}. The codes of
// service::Refused ("busy", "not_identifiable", "not_found", "finished", "bad_request",
// "bad_session") pass through unchanged.
namespace code {
inline constexpr const char* kBadJson = "bad_json";
inline constexpr const char* kBadRequest = "bad_request";
inline constexpr const char* kUnknownCommand = "unknown_command";
inline constexpr const char* kUnauthenticated = "unauthenticated";
inline constexpr const char* kAuthFailed = "auth_failed";
inline constexpr const char* kLineTooLong = "line_too_long";
inline constexpr const char* kTooManyClients = "too_many_clients";
inline constexpr const char* kUnavailable = "unavailable";
inline constexpr const char* kInternal = "internal";
}  // namespace code

// A request member has the wrong type or value; `what()` names the member. Becomes bad_request.
class BadRequest : public Error {
 public:
  using Error::Error;
};

// The members of a `start` or `plan` request (plan, poses, plan_file, target_mm, noise_mm; all
// optional; those absent keep their value in `defaults`), checked for type and plain range. Other
// members but id, cmd and token are refused so that a misspelt option is not silently ignored.
// Throws BadRequest.
service::StartRequest parseStartRequest(const nlohmann::json& request,
                                        const service::StartRequest& defaults = {});
// The inverse, for the client; only the members that are set.
nlohmann::json toJson(const service::StartRequest& request);

const char* planKindName(PlanKind kind);
// Throws BadRequest for an unknown name.
PlanKind parsePlanKind(const std::string& name);

nlohmann::json toJson(const service::SessionStatus& status);
nlohmann::json toJson(const service::LiveReading& reading);
nlohmann::json toJson(const std::vector<SessionInfo>& sessions);

// A string member when present (else `fallback`); throws BadRequest when it is not a string.
std::string optionalString(const nlohmann::json& request, const char* key,
                           const std::string& fallback = {});

// One protocol line: compact JSON, invalid UTF-8 replaced rather than thrown on, and '\n'.
std::string toLine(const nlohmann::json& message);

nlohmann::json errorResponse(const nlohmann::json& id, const std::string& code,
                             const std::string& message);

}  // namespace zerocal::control
