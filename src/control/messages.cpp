#include "zerocal/control/messages.h"

namespace zerocal::control {

using nlohmann::json;

std::string optionalString(const json& request, const char* key, const std::string& fallback) {
  const auto it = request.find(key);
  if (it == request.end() || it->is_null()) return fallback;
  if (!it->is_string()) throw BadRequest(std::string(key) + ": expected a string");
  return it->get<std::string>();
}

std::string toLine(const json& message) {
  return message.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
}

json errorResponse(const json& id, const std::string& code, const std::string& message) {
  return {{"id", id}, {"ok", false}, {"error", {{"code", code}, {"message", message}}}};
}

}  // namespace zerocal::control
