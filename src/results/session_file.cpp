#include "zerocal/results/session_file.h"

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {
namespace {

using Json = nlohmann::json;

constexpr const char* kSessionWhere = "session.json";

}  // namespace

const char* sessionKindName(SessionKind kind) {
  switch (kind) {
    case SessionKind::kCalibration:
      return "calibration";
    case SessionKind::kVerification:
      return "verification";
    case SessionKind::kReference:
      return "reference";
    case SessionKind::kCheck:
      return "check";
    case SessionKind::kRestore:
      return "restore";
  }
  return "calibration";
}

SessionKind sessionKindFromName(const std::string& name, const std::string& where) {
  for (const SessionKind k : {SessionKind::kCalibration, SessionKind::kVerification,
                              SessionKind::kReference, SessionKind::kCheck, SessionKind::kRestore})
    if (name == sessionKindName(k)) return k;
  throw InputError(where + ": kind '" + name +
                   "' is not calibration, reference, check, restore or verification");
}

Json toJson(const SessionFile& s) {
  Json plan = toJson(s.plan);
  plan["target_mm"] = {s.target_mm.x(), s.target_mm.y(), s.target_mm.z()};
  plan["noise_mm"] = s.noise_mm;
  if (!s.placement_centres_mm.empty()) {
    Json& centres = plan["placement_centres_mm"] = Json::array();
    for (const Eigen::Vector3d& c : s.placement_centres_mm)
      centres.push_back({c.x(), c.y(), c.z()});
  }
  Json j{{"format", s.format},
         {"id", s.id},
         {"created_unix_s", s.created_unix_s},
         {"kind", sessionKindName(s.kind)},
         {"plan", plan},
         {"config", s.config}};
  if (!s.verifies.empty()) j["verifies"] = s.verifies;
  if (!s.reference.empty()) {
    j["reference"] = s.reference;
    j["reference_poses"] = s.reference_poses;
  }
  if (!s.model_from.empty()) j["model_from"] = s.model_from;
  return j;
}

SessionFile sessionFileFromJson(const Json& json) {
  const JsonReader j(json, kSessionWhere);
  SessionFile s;
  s.format = j.string("format");
  s.id = j.string("id");
  s.created_unix_s = j.has("created_unix_s") ? j.integer64("created_unix_s") : 0;
  if (j.has("kind")) s.kind = sessionKindFromName(j.string("kind"), kSessionWhere);
  s.verifies = j.has("verifies") ? j.string("verifies") : "";
  if (j.has("reference")) {
    s.reference = j.string("reference");
    for (const Json& pose : j.array("reference_poses")) {
      if (!pose.is_number_integer() || pose.get<int>() < 1)
        throw InputError(std::string(kSessionWhere) +
                         ": 'reference_poses' holds something other than a 1-based pose");
      s.reference_poses.push_back(pose.get<int>());
    }
  }
  s.model_from = j.has("model_from") ? j.string("model_from") : "";
  const bool measured_against = s.kind == SessionKind::kCheck || s.kind == SessionKind::kRestore;
  if (measured_against && s.reference.empty())
    throw InputError(std::string(kSessionWhere) + ": a " + sessionKindName(s.kind) +
                     " names its 'reference'");
  const JsonReader plan = j.object("plan");
  s.plan = planFromJson(plan.json(), plan.where());
  const std::vector<double> target = plan.numbers("target_mm", 3);
  s.target_mm = {target[0], target[1], target[2]};
  s.noise_mm = plan.number("noise_mm");
  if (plan.present("placement_centres_mm")) {
    const Json& centres = plan.array("placement_centres_mm");
    for (std::size_t i = 0; i < centres.size(); ++i) {
      const std::vector<double> c = JsonReader::numbersOf(
          centres[i], 3, plan.where() + " placement_centres_mm[" + std::to_string(i) + "]");
      s.placement_centres_mm.emplace_back(c[0], c[1], c[2]);
    }
  }
  if (!s.reference.empty() && s.reference_poses.size() != s.plan.poses.size())
    throw InputError(std::string(kSessionWhere) + ": 'reference_poses' names " +
                     std::to_string(s.reference_poses.size()) + " poses for a plan of " +
                     std::to_string(s.plan.poses.size()));
  s.config = j.has("config") ? j.at("config") : Json::object();
  return s;
}

}  // namespace zerocal
