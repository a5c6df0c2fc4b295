// The control port's requests and answers in the service's terms: the conversions between
// protocol objects and the types of SessionControl, for the server. The wire format itself is in
// messages.h.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/control/messages.h"
#include "zerocal/service/session_control.h"

namespace zerocal::control {

// The members of a `start` or `plan` request (plan, poses, plan_file, target_mm, noise_mm,
// placements; all
// optional; those absent keep their value in `defaults`), checked for type and plain range. Other
// members but id, cmd and token are refused so that a misspelt option is not silently ignored.
// Throws BadRequest.
service::StartRequest parseStartRequest(const nlohmann::json& request,
                                        const service::StartRequest& defaults = {});

// The members of a `resume` request: session (the latest unfinished when absent) and skip_pose
// (1-based, 1..kMaxPlanPoses). Others but id, cmd and token are refused. Throws BadRequest.
service::ResumeRequest parseResumeRequest(const nlohmann::json& request);

// The members of a `continue` request: centre_mm ([x, y, z] mm, finite; absent or null: the
// placement's planned centre). Others but id, cmd and token are refused. Throws BadRequest.
service::ContinueRequest parseContinueRequest(const nlohmann::json& request);

// The members of an `apply` request: session (the latest finished when absent) and confirm (a
// boolean; the manager refuses the apply unless true), of an `acknowledge` request (the same),
// and of a `verify` request: session. Others but id, cmd and token are refused. Throw BadRequest.
service::ApplyRequest parseApplyRequest(const nlohmann::json& request);
service::AcknowledgeRequest parseAcknowledgeRequest(const nlohmann::json& request);
service::VerifyRequest parseVerifyRequest(const nlohmann::json& request);

// A page of the `sessions` list, newest first: at most `limit` sessions older than `cursor`
// (the previous page's `next`; empty: from the newest).
struct SessionsPage {
  static constexpr int kDefaultLimit = 100;  // a request without `limit`
  static constexpr int kMaxLimit = 1000;
  int limit = kDefaultLimit;
  std::string cursor;
};

// The members of a `sessions` request: limit (1..kMaxLimit) and cursor (a string). Other members
// are ignored, as old clients send none. Throws BadRequest.
SessionsPage parseSessionsRequest(const nlohmann::json& request);

// The members of the `sessions` answer for `page` of `sessions` (oldest first, as the store lists
// them): "sessions" (newest first), "total" and, when older ones remain, "next".
nlohmann::json sessionsPage(const std::vector<SessionInfo>& sessions, const SessionsPage& page);

// The robot a `history` request names among those the record knows: by "serial" and, when two
// robots of different types share it, "robot_type"; with neither, the record's only robot.
// Throws BadRequest naming the robots there are when none or several match.
record::RobotId parseHistoryRequest(const nlohmann::json& request,
                                    const std::vector<record::RobotSummary>& robots);
// The `robots` answer's list, and one session of a `history` answer (docs/protocol.md).
nlohmann::json toJson(const std::vector<record::RobotSummary>& robots);
nlohmann::json toJson(const record::HistoryEntry& entry);

const char* planKindName(PlanKind kind);
// Throws BadRequest for an unknown name.
PlanKind parsePlanKind(const std::string& name);

nlohmann::json toJson(const service::SessionStatus& status);
// A session's latest apply (the `result` answer's `apply`): outcome, when, the values before and
// written (rad, joints 1..6; absent for a verification alone), the verification's session and
// its verdict, and a later verification's.
nlohmann::json toJson(const apply::ApplyRecord& applied);
nlohmann::json toJson(const service::LiveReading& reading);
nlohmann::json toJson(const std::vector<SessionInfo>& sessions);
// An event line's object: {"event": "plan" | "state" | "pose" | "remeasure" | "result" |
// "apply_progress" | "apply" | "placement", ...}.
nlohmann::json toJson(const service::SessionEvent& event);

}  // namespace zerocal::control
