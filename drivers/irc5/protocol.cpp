#include "zerocal/irc5/protocol.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <string>

#include "zerocal/irc5/errors.h"

namespace zerocal {
namespace irc5 {
namespace {

bool isSpace(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; }

// Calls f(field) for each run of non-space characters, in order.
template <typename F>
void forEachField(std::string_view text, F&& f) {
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && isSpace(text[i])) ++i;
    std::size_t j = i;
    while (j < text.size() && !isSpace(text[j])) ++j;
    if (j > i) f(text.substr(i, j - i));
    i = j;
  }
}

std::vector<std::string> splitFields(std::string_view text) {
  std::vector<std::string> out;
  forEachField(text, [&](std::string_view field) { out.emplace_back(field); });
  return out;
}

bool parseInt(std::string_view s, int* value) {
  if (s.empty() || s.size() > 3) return false;
  int v = 0;
  for (char c : s) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
    v = 10 * v + (c - '0');
  }
  *value = v;
  return true;
}

}  // namespace

void formatRequest(std::string& out, int code, const Param* params, std::size_t count) {
  out.clear();  // its capacity is kept: a request in the servo cycle allocates nothing
  fmt::format_to(std::back_inserter(out), FMT_STRING("{:02d} "), code);
  for (std::size_t i = 0; i < count; ++i) {
    const Param& p = params[i];
    // Values that round to zero would print "-0.00000"; RAPID reads it but logs read oddly.
    const double v = std::abs(p.value) < 0.5 * std::pow(10.0, -p.decimals) ? 0.0 : p.value;
    fmt::format_to(std::back_inserter(out), FMT_STRING("{:+.{}f} "), v, p.decimals);
  }
  out += '#';
}

std::string formatRequest(int code, const std::vector<Param>& params) {
  std::string out;
  formatRequest(out, code, params.data(), params.size());
  return out;
}

std::string formatRequest(int code, std::initializer_list<Param> params) {
  std::string out;
  formatRequest(out, code, params.begin(), params.size());
  return out;
}

void checkRequest(std::string_view request) {
  const auto refuse = [&](const std::string& why) {
    throw RequestRefusedError("request \"" + std::string(request.substr(0, 90)) +
                              "\" refused: " + why);
  };
  if (request.size() > kMaxMessageLength)
    refuse(std::to_string(request.size()) + " characters, the RAPID limit is 80");
  const std::size_t hash = request.find('#');
  if (hash == std::string_view::npos) refuse("no terminating '#'");
  // Upstream's server reads one segment; bytes after '#' would start the next request.
  if (hash + 1 != request.size()) refuse("characters after '#'");
  std::size_t i = 0;
  while (i < request.size() && std::isdigit(static_cast<unsigned char>(request[i]))) ++i;
  if (i == 0 || i > 2 || request[i] != ' ') refuse("the code must be 1 or 2 digits and a space");
}

ParsedRequest parseRequest(std::string_view request) {
  ParsedRequest out;
  const std::size_t hash = request.find('#');
  const std::string_view body = request.substr(0, hash);
  std::size_t i = 0;
  while (i < body.size() && isSpace(body[i])) ++i;
  std::size_t j = i;
  while (j < body.size() && std::isdigit(static_cast<unsigned char>(body[j]))) ++j;
  if (j == i || j - i > 2) return out;
  out.code = std::atoi(std::string(body.substr(i, j - i)).c_str());
  out.valid = true;
  // Upstream's rule: a parameter counts only when a space follows it.
  std::size_t pos = j;
  while (pos < body.size()) {
    while (pos < body.size() && body[pos] == ' ') ++pos;
    std::size_t end = pos;
    while (end < body.size() && body[end] != ' ') ++end;
    if (end == pos) break;
    if (end >= body.size()) break;  // written against '#': not counted
    const std::string token(body.substr(pos, end - pos));
    char* stop = nullptr;
    const double v = std::strtod(token.c_str(), &stop);
    if (stop == token.c_str() || *stop != '\0' || !std::isfinite(v)) {
      out.valid = false;
      return out;
    }
    out.params.push_back(v);
    pos = end;
  }
  return out;
}

ReplyView parseReplyView(std::string_view text) {
  ReplyView r;
  std::string_view first, second;
  std::size_t count = 0;
  forEachField(text, [&](std::string_view field) {
    if (count == 0) first = field;
    if (count == 1) second = field;
    if (count >= 2 && count - 2 < kMaxReplyFields) r.fields[count - 2] = field;
    ++count;
  });
  int ok = -1;
  if (count < 2 || !parseInt(first, &r.code) || !parseInt(second, &ok) || ok > 1) {
    throw ProtocolError("unreadable reply \"" + std::string(text.substr(0, 100)) + "\"");
  }
  r.ok = ok == 1;
  r.field_count = count - 2;
  // data: the text after the second field, trimmed (robot info may contain spaces).
  std::string_view rest =
      text.substr(static_cast<std::size_t>(second.data() + second.size() - text.data()));
  while (!rest.empty() && isSpace(rest.front())) rest.remove_prefix(1);
  while (!rest.empty() && isSpace(rest.back())) rest.remove_suffix(1);
  r.data = rest;
  return r;
}

Reply parseReply(std::string_view text) {
  const ReplyView v = parseReplyView(text);
  Reply r;
  r.code = v.code;
  r.ok = v.ok;
  r.data = std::string(v.data);
  // Every field, however many: the fields after the first two are those of the data.
  r.fields = splitFields(v.data);
  return r;
}

int expectedReplyFields(int code) {
  switch (code) {
    case kReadPose:
      return 7;
    case kReadJoints:
    case kReadExternalAxes:
    case kReadCalOffset:
    case kReadJointBounds:
    case kReadMotorAngles:
      return 6;
    case kSimBeamSpot:
      return 3;
    case kSimWorldId:
      return 2;
    case kRobotInfo:
    case kSearchRun:  // "0", or "1" and the six joints where the signal rose
      return -1;
    default:
      return 0;
  }
}

Completeness replyCompleteness(std::string_view buffer, int expected_fields) {
  std::string_view first, second;
  std::size_t count = 0;
  forEachField(buffer, [&](std::string_view field) {
    if (count == 0) first = field;
    if (count == 1) second = field;
    ++count;
  });
  const bool trailing_space = !buffer.empty() && isSpace(buffer.back());
  // Not the start of a reply at all: complete as far as waiting goes, parseReply will refuse it.
  int number = 0;
  if (count > 0 && (count > 1 || trailing_space) && !parseInt(first, &number)) {
    return Completeness::kComplete;
  }
  if (count < 2 || (count == 2 && !trailing_space)) return Completeness::kNeedMore;
  // A refusal carries no fixed field count ("30 0 not supported" from us, "4 0 " upstream).
  if (second == "0") return Completeness::kMaybe;
  const std::size_t data = count - 2;
  if (expected_fields < 0) {
    // Robot info: "serial*version*type", the type may contain spaces.
    const std::size_t stars = std::count(buffer.begin(), buffer.end(), '*');
    return stars >= 2 && buffer.back() != '*' ? Completeness::kMaybe : Completeness::kNeedMore;
  }
  const auto want = static_cast<std::size_t>(expected_fields);
  if (data < want) return Completeness::kNeedMore;
  if (want == 0) return Completeness::kComplete;
  return trailing_space ? Completeness::kComplete : Completeness::kMaybe;
}

}  // namespace irc5
}  // namespace zerocal
