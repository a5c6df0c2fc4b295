// The control port's wire format (docs/protocol.md): its version, error codes and lines. Needs
// nothing of the service, so that the shop-floor client links only this and the transport.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "zerocal/error.h"

namespace zerocal::control {

// Raised when a change would break an existing client: a removed command or member, a changed
// meaning. New commands, members and events do not change it.
inline constexpr int kProtocolVersion = 1;
inline constexpr std::uint16_t kDefaultPort = 7450;

// Error codes of a response {"ok": false, "error": {"code": ..., "message": ...}}. The codes of
// service::Refused ("busy", "not_identifiable", "not_found", "finished", "bad_request",
// "bad_session", "damaged", "not_waiting", ...) pass through unchanged.
namespace code {
inline constexpr const char* kBadJson = "bad_json";
inline constexpr const char* kBadRequest = "bad_request";
inline constexpr const char* kUnknownCommand = "unknown_command";
inline constexpr const char* kUnauthenticated = "unauthenticated";
inline constexpr const char* kAuthFailed = "auth_failed";
inline constexpr const char* kForbidden = "forbidden";  // the login's role may not (roles.h)
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

// Nesting deeper than any request has is refused while parsing, before anything recurses over
// it (copying, serialising and destroying a json are recursive).
inline constexpr int kMaxRequestDepth = 16;

// A request line nested deeper than kMaxRequestDepth. Becomes bad_json.
class RequestTooDeep : public Error {
 public:
  RequestTooDeep();
};

// One request line as JSON (any JSON value: the caller checks that it is an object). Throws
// RequestTooDeep, or nlohmann::json::exception when the line is not JSON.
nlohmann::json parseRequestLine(const std::string& line);

// A string member when present (else `fallback`); throws BadRequest when it is not a string.
std::string optionalString(const nlohmann::json& request, const char* key,
                           const std::string& fallback = {});

// One protocol line: compact JSON, invalid UTF-8 replaced rather than thrown on, and '\n'.
std::string toLine(const nlohmann::json& message);

nlohmann::json errorResponse(const nlohmann::json& id, const std::string& code,
                             const std::string& message);

}  // namespace zerocal::control
