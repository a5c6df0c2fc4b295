#include "zerocal/control/messages.h"

namespace zerocal::control {

using nlohmann::json;

RequestTooDeep::RequestTooDeep()
    : Error("nested deeper than " + std::to_string(kMaxRequestDepth) + " levels") {}

json parseRequestLine(const std::string& line) {
  return json::parse(line, [](int depth, json::parse_event_t, json&) {
    if (depth > kMaxRequestDepth) throw RequestTooDeep();
    return true;
  });
}

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
