#include "zerocal/control/protocol.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <set>
#include <variant>

#include "zerocal/calib/format.h"

namespace zerocal::control {

using nlohmann::json;

json toJson(const service::SessionStatus& s) {
  // NaN (not identifiable) becomes null: JSON has no NaN and nlohmann writes null for it anyway.
  auto sigmas = [](const std::vector<double>& v) {
    json a = json::array();
    for (double x : v) a.push_back(std::isfinite(x) ? json(x) : json(nullptr));
    return a;
  };
  json j{{"state", service::stateName(s.state)},
         {"active", service::isActive(s.state)},
         {"backend", s.backend},
         {"session", s.session_id},
         {"pose", s.pose},
         {"pose_count", s.pose_count},
         {"recorded", s.recorded},
         {"resumed_from", s.resumed_from},
         {"last_servo_error_um", s.last_servo_error_um},
         {"servo_zone_um", s.servo_zone_um},
         // While servoing, the latest reading's distance from the centre; null otherwise, or
         // when the spot is off the detector.
         {"live_servo_error_um", s.live_servo_error_um && std::isfinite(*s.live_servo_error_um)
                                     ? json(*s.live_servo_error_um)
                                     : json(nullptr)},
         {"predicted_sigma_deg", sigmas(s.predicted_sigma_deg)},
         {"achieved_sigma_deg", sigmas(s.achieved_sigma_deg)},
         {"cell_time_s", s.cell_time_s}};
  if (!s.message.empty()) j["message"] = s.message;
  if (s.skippable_pose > 0) j["skippable_pose"] = s.skippable_pose;
  if (!s.apply.empty()) j["apply"] = s.apply;
  if (!s.suggestion.empty()) j["suggestion"] = s.suggestion;
  if (!s.suggested_kind.empty()) j["suggested_kind"] = s.suggested_kind;
  if (s.placement_count > 1) {
    j["placement_count"] = s.placement_count;
    j["placement"] = s.placement;
  }
  if (s.state == service::SessionState::kAwaitingPlacement) {
    j["next_placement"] = s.next_placement;
    j["next_centre_mm"] = {s.next_centre_mm.x(), s.next_centre_mm.y(), s.next_centre_mm.z()};
  }
  return j;
}

json toJson(const apply::ApplyRecord& a) {
  const auto offsets = [](const apply::Offsets& o) {
    json out = json::array();
    for (const apply::MeasuredOffset& m : o)
      out.push_back({{"value_deg", m.value_deg}, {"sigma_deg", m.sigma_deg}});
    return out;
  };
  json j{{"outcome", a.outcome}, {"time_unix_s", a.time_unix_s}, {"message", a.message}};
  if (a.outcome != "pass" && a.outcome != "fail") {
    j["before_rad"] = a.before_rad;
    j["written_rad"] = a.written_rad;
  }
  if (!a.verification.empty()) j["verification"] = a.verification;
  if (a.remaining) j["remaining"] = offsets(*a.remaining);
  if (a.later_check)
    j["later_check"] = {{"outcome", a.later_check->outcome},
                        {"session", a.later_check->session},
                        {"message", a.later_check->message},
                        {"remaining", offsets(a.later_check->remaining)}};
  return j;
}

json toJson(const service::LiveReading& live) {
  const auto& r = live.reading;
  return {{"u_mm", r.spot.u_mm},
          {"v_mm", r.spot.v_mm},
          {"u_se_mm", r.se.u_mm},
          {"v_se_mm", r.se.v_mm},
          {"sum_v", r.sum_v},
          {"spot_present", r.spot_present},
          {"in_valid_zone", r.in_valid_zone},
          {"time_s", r.time_s},
          {"during_session", live.during_session}};
}

json toJson(const std::vector<SessionInfo>& sessions) {
  json a = json::array();
  for (const auto& s : sessions) {
    a.push_back({{"id", s.id},
                 {"dir", s.dir},
                 {"finished", s.finished},
                 {"planned_poses", s.planned_poses},
                 {"recorded_poses", s.recorded_poses}});
    if (s.skipped_poses > 0) a.back()["skipped_poses"] = s.skipped_poses;
    if (!s.damaged.empty()) a.back()["damaged"] = s.damaged;
    if (s.kind != SessionKind::kCalibration) a.back()["kind"] = sessionKindName(s.kind);
    if (!s.verifies.empty()) a.back()["verifies"] = s.verifies;
    if (!s.closed.empty()) a.back()["closed"] = s.closed;
  }
  return a;
}

json sessionsPage(const std::vector<SessionInfo>& sessions, const SessionsPage& page) {
  // Ids are creation times, and the list is sorted by them: the cursor, the last id of the page
  // before, stays valid while sessions are created or removed.
  auto end = sessions.end();
  if (!page.cursor.empty())
    end = std::lower_bound(sessions.begin(), sessions.end(), page.cursor,
                           [](const SessionInfo& s, const std::string& id) { return s.id < id; });
  const auto count = std::min<std::ptrdiff_t>(page.limit, end - sessions.begin());
  const std::vector<SessionInfo> newest_first(std::make_reverse_iterator(end),
                                              std::make_reverse_iterator(end - count));
  json r{{"sessions", toJson(newest_first)}, {"total", sessions.size()}};
  if (end - count != sessions.begin()) r["next"] = newest_first.back().id;
  return r;
}

namespace {

// Offsets by name; null where not identifiable.
json sigmaObject(const std::vector<double>& sigma) {
  json j = json::object();
  for (std::size_t k = 0; k < sigma.size(); ++k)
    j[unknownName(static_cast<int>(k))] = std::isfinite(sigma[k]) ? json(sigma[k]) : json();
  return j;
}

struct EventJson {
  json operator()(const service::PlanEvent& e) const {
    return {{"event", "plan"},
            {"session", e.session},
            {"pose_count", e.pose_count},
            {"description", e.description},
            {"predicted_sigma_deg", sigmaObject(e.predicted_sigma_deg)}};
  }
  json operator()(const service::StateEvent& e) const {
    json j{{"event", "state"}, {"state", service::stateName(e.state)}, {"session", e.session},
           {"pose", e.pose},   {"pose_count", e.pose_count},           {"recorded", e.recorded}};
    if (!e.message.empty()) j["message"] = e.message;
    return j;
  }
  json operator()(const service::PoseEvent& e) const {
    const PoseRecord& r = e.record;
    json j{{"event", "pose"}, {"session", e.session}, {"pose", r.planIndex() + 1}};
    if (r.measured()) {
      j["servo_error_um"] = r.servo.final_error_um;
      j["servo_moves"] = r.servo.moves;
    } else {
      j["skipped"] = r.skipped;
    }
    if (r.remeasure_of >= 0) j["again"] = true;
    j["pose_count"] = e.pose_count;
    return j;
  }
  json operator()(const service::PlacementEvent& e) const {
    return {{"event", "placement"},
            {"session", e.session},
            {"placement", e.placement},
            {"placement_count", e.placement_count},
            {"centre_mm", {e.centre_mm.x(), e.centre_mm.y(), e.centre_mm.z()}},
            {"message", e.message}};
  }
  json operator()(const service::RemeasureEvent& e) const {
    return {{"event", "remeasure"}, {"session", e.session}, {"poses", e.poses}};
  }
  json operator()(const service::ApplyProgressEvent& e) const {
    return {{"event", "apply_progress"}, {"session", e.session}, {"message", e.message}};
  }
  json operator()(const service::ApplyEvent& e) const {
    json j{{"event", "apply"},
           {"session", e.session},
           {"outcome", service::applyOutcomeName(e.outcome)},
           {"message", e.message}};
    if (!e.verification.empty()) j["verification"] = e.verification;
    if (!e.before_rad.empty()) j["before_rad"] = e.before_rad;
    if (!e.written_rad.empty()) j["written_rad"] = e.written_rad;
    if (!e.remaining_deg.empty()) {
      json remaining = json::object();
      for (std::size_t k = 0; k < e.remaining_deg.size(); ++k)
        remaining[unknownName(static_cast<int>(k))] = {{"value", e.remaining_deg[k]},
                                                       {"sigma", e.remaining_sigma_deg[k]}};
      j["remaining_deg"] = remaining;
    }
    return j;
  }
  json operator()(const service::ResultEvent& e) const {
    json j{{"event", "result"},
           {"session", e.session},
           {"converged", e.report.converged},
           {"achieved_sigma_deg", sigmaObject(e.achieved_sigma_deg)},
           {"parameters", toJson(e.report).at("parameters")}};
    if (!e.report_error.empty()) j["report_error"] = e.report_error;
    return j;
  }
};

}  // namespace

json toJson(const service::SessionEvent& event) { return std::visit(EventJson{}, event); }

namespace {

std::string robotText(const record::RobotId& r) { return r.robot_type + " serial " + r.serial; }

json offsetsJson(const record::RecordedOffsets& offsets) {
  json o = json::object();
  for (int k = 0; k < kOffsetCount; ++k)
    o[unknownName(k)] =
        offsets[k] ? json{{"value", offsets[k]->value_deg}, {"sigma", offsets[k]->sigma_deg}}
                   : json(nullptr);
  return o;
}

json valuesJson(const std::optional<std::array<double, 6>>& v) {
  return v ? json(*v) : json(nullptr);
}

}  // namespace

record::RobotId parseHistoryRequest(const json& request,
                                    const std::vector<record::RobotSummary>& robots) {
  const auto member = [&](const char* name) -> std::optional<std::string> {
    const auto it = request.find(name);
    if (it == request.end() || it->is_null()) return std::nullopt;
    if (!it->is_string()) throw BadRequest(std::string(name) + ": expected a string");
    return it->get<std::string>();
  };
  const std::optional<std::string> serial = member("serial"), type = member("robot_type");
  std::vector<record::RobotId> matching;
  for (const record::RobotSummary& r : robots)
    if ((!serial || r.id.serial == *serial) && (!type || r.id.robot_type == *type))
      matching.push_back(r.id);
  if (matching.size() == 1) return matching.front();
  std::string known;
  for (const record::RobotSummary& r : robots)
    known += (known.empty() ? "" : "; ") + robotText(r.id);
  if (robots.empty()) throw BadRequest("the record knows no robot yet");
  if (matching.empty())
    throw BadRequest("the record knows no robot" + (serial ? " of serial " + *serial : "") +
                     (type ? " of type " + *type : "") + "; it knows " + known);
  throw BadRequest(std::string(serial ? "serial " + *serial + " names" : "the record knows") +
                   " several robots (" + known + "): name one by serial and robot_type");
}

json toJson(const std::vector<record::RobotSummary>& robots) {
  json a = json::array();
  for (const record::RobotSummary& r : robots)
    a.push_back({{"robot_type", r.id.robot_type},
                 {"serial", r.id.serial},
                 {"software_version", r.software_version},
                 {"sessions", r.sessions},
                 {"first_unix_s", r.first_unix_s},
                 {"last_unix_s", r.last_unix_s}});
  return a;
}

json toJson(const record::HistoryEntry& entry) {
  const record::SessionEntry& s = entry.session;
  json events = json::array();
  for (const record::ControllerEvent& e : entry.events) {
    json j{{"kind", record::controllerEventKindName(e.kind)},
           {"time_unix_s", e.time_unix_s},
           {"outcome", e.outcome},
           {"before_rad", valuesJson(e.before_rad)},
           {"after_rad", valuesJson(e.after_rad)},
           {"message", e.message}};
    if (!e.verification.empty()) j["verification"] = e.verification;
    if (e.kind == record::ControllerEventKind::kVerification)
      j["remaining"] = offsetsJson(e.remaining);
    events.push_back(j);
  }
  json j{{"session", s.session},
         {"kind", s.kind},
         {"usable", s.usable ? json(*s.usable) : json(nullptr)},
         {"reasons", s.reasons},
         {"converged", s.converged},
         {"poses_used", s.poses_used},
         {"offsets", offsetsJson(s.offsets)},
         {"cell_time_s", s.cell_time_s ? json(*s.cell_time_s) : json(nullptr)},
         {"started_unix_s", s.started_unix_s},
         {"finished_unix_s", s.finished_unix_s ? json(*s.finished_unix_s) : json(nullptr)},
         {"software_version", s.software_version},
         {"cal_offset_rad", valuesJson(s.cal_offset_rad)},
         {"events", events}};
  if (!s.verifies.empty()) j["verifies"] = s.verifies;
  if (!s.model_from.empty()) j["model_from"] = s.model_from;
  if (!s.model_file.empty()) j["model_file"] = s.model_file;
  if (!s.reference.empty()) j["reference"] = s.reference;
  return j;
}

}  // namespace zerocal::control
