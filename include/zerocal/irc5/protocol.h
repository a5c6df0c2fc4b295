// The open_abb text protocol as zerocal speaks it (docs/irc5.md gives the grammar): request
// formatting and checking, reply parsing. Shared by the client and the simulated controller so
// that both sides agree on one grammar; no I/O here.
#pragma once

#include <array>
#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace zerocal {
namespace irc5 {

// Request codes. 0..9 and 98/99 are upstream's; 30..36 are upstream's buffered and circular moves
// (not supported by us); 40..49 are zerocal's extensions (43 and 44 answered by zerocal-sim only,
// not by the RAPID module).
enum Code : int {
  kPing = 0,
  kMoveLinear = 1,
  kMoveJoints = 2,
  kReadPose = 3,
  kReadJoints = 4,
  kReadExternalAxes = 5,
  kSetTool = 6,
  kSetWorkObject = 7,
  kSetSpeed = 8,
  kSetZone = 9,
  kStop = 40,             // extension: StopMove, reply at once
  kReadCalOffset = 41,    // extension: MOC MOTOR_CALIB cal_offset of the six motors, radians
  kReadJointBounds = 42,  // extension: 1 param, 0 = lower, 1 = upper bounds, degrees
  kSimBeamSpot = 43,      // simulator only: present flag, u, v (mm) of the beam on the PSD plane
  kSimWorldId = 44,       // simulator only: hash of the simulated world (16 hex digits), seed
  kWriteCalOffset = 45,   // extension: 2 params, joint 1..6 and MOC cal_offset (rad, [0, 2 pi))
  kRestart = 46,          // extension: reply, then restart the controller (MOC changes take effect)
  kSearchSpiral = 47,     // extension: 7 params, one row of the spot search's spiral (joints)
  kReadMotorAngles = 48,  // extension: RAPID ReadMotor of the six motors, radians
  kSearchRun = 49,        // extension: 4 params, one run of the spiral; the joints where light rose
  kRobotInfo = 98,
  kClose = 99,
};

// RAPID strings hold at most 80 characters: the limit for every request and reply (without LF).
constexpr std::size_t kMaxMessageLength = 80;

// Decimals on the wire. Joints at 1e-5 deg match RAPID's float32 num near 100 deg.
constexpr int kJointDecimals = 5;
constexpr int kXyzDecimals = 3;
constexpr int kQuatDecimals = 6;
constexpr int kSpeedDecimals = 2;

struct Param {
  double value;
  int decimals;
};

// "CC p1 p2 ... #": code zero-padded to two digits, each parameter with an explicit sign and the
// given decimals, one space after every field. Does not check the length (see checkRequest).
std::string formatRequest(int code, std::initializer_list<Param> params = {});
std::string formatRequest(int code, const std::vector<Param>& params);
// The same text into `out` (replacing what it held): no allocation while out's capacity holds it.
void formatRequest(std::string& out, int code, const Param* params, std::size_t count);

// Throws RequestRefusedError when the text is not one well-formed request: longer than 80
// characters, no '#', anything after '#', a code that is not 1..2 digits.
void checkRequest(std::string_view request);

// A request as the server reads it, with upstream's counting rule: only parameters followed by a
// space count (a number written against '#' is dropped), so the count check then fails.
struct ParsedRequest {
  bool valid = false;  // false: no code could be read
  int code = -1;
  std::vector<double> params;
};
ParsedRequest parseRequest(std::string_view request);

// One reply "rcode ok [data]" (the LF, if any, removed).
struct Reply {
  int code = -1;
  bool ok = false;
  std::string data;                 // everything after "rcode ok ", trimmed
  std::vector<std::string> fields;  // data split on spaces
};
// Throws ProtocolError when the text does not start with two integers "rcode ok".
Reply parseReply(std::string_view text);

// Room for every field of an 80-character reply (a field and its space take 2 at least).
constexpr std::size_t kMaxReplyFields = kMaxMessageLength / 2;

// The same reply parsed in place, without allocating: views into the text, valid while it is.
// Fields past kMaxReplyFields are counted, not kept.
struct ReplyView {
  int code = -1;
  bool ok = false;
  std::string_view data;
  std::array<std::string_view, kMaxReplyFields> fields{};
  std::size_t field_count = 0;
};
// Throws ProtocolError as parseReply (building that error's message allocates).
ReplyView parseReplyView(std::string_view text);

// Number of data fields (after rcode and ok) the reply to a request code carries when ok = 1.
// -1: variable (robot info, "serial*version*type", may contain spaces).
int expectedReplyFields(int code);

// For servers that end replies with no LF (upstream): how far a buffer holds one whole reply.
enum class Completeness {
  kNeedMore,  // certainly incomplete
  kMaybe,     // every expected field has begun; the last may still be growing
  kComplete,  // complete: the expected fields are there and followed by a space
};
Completeness replyCompleteness(std::string_view buffer, int expected_fields);

}  // namespace irc5
}  // namespace zerocal
