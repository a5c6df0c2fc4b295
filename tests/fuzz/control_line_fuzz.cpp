// Fuzz target: one line on the control port, as the server takes it apart: the JSON (with its
// depth limit), then the members of the command it names. A line that is not JSON (or holds a
// number beyond a double) throws a json exception, answered with bad_json; a request is refused
// with BadRequest. Anything else would reach a client as an internal error, or crash the daemon.
#include <nlohmann/json.hpp>

#include "fuzz_input.h"
#include "zerocal/control/messages.h"
#include "zerocal/control/protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace zerocal::control;
  nlohmann::json request;
  try {
    request = parseRequestLine(zerocal::fuzz::text(data, size));
  } catch (const RequestTooDeep&) {
    return 0;
  } catch (const nlohmann::json::exception&) {
    return 0;
  }
  if (!request.is_object()) return 0;
  const auto cmd = request.find("cmd");
  if (cmd == request.end() || !cmd->is_string()) return 0;
  const std::string name = cmd->get<std::string>();
  try {
    if (name == "start" || name == "plan") parseStartRequest(request);
    if (name == "resume") parseResumeRequest(request);
    if (name == "continue") parseContinueRequest(request);
    if (name == "apply") parseApplyRequest(request);
    if (name == "acknowledge") parseAcknowledgeRequest(request);
    if (name == "verify") parseVerifyRequest(request);
    if (name == "sessions") parseSessionsRequest(request);
    optionalString(request, "token");
    toLine(errorResponse(request.contains("id") ? request["id"] : nullptr, "bad_request", name));
  } catch (const BadRequest&) {
  }
  return 0;
}
