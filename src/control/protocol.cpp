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

}  // namespace zerocal::control
