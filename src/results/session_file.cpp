#include "zerocal/results/session_file.h"

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {
namespace {

using Json = nlohmann::json;

constexpr const char* kSessionWhere = "session.json";

}  // namespace

const char* sessionKindName(SessionKind kind) {
  return kind == SessionKind::kVerification ? "verification" : "calibration";
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
  return j;
}

SessionFile sessionFileFromJson(const Json& json) {
  const JsonReader j(json, kSessionWhere);
  SessionFile s;
  s.format = j.string("format");
  s.id = j.string("id");
  s.created_unix_s = j.has("created_unix_s") ? j.integer64("created_unix_s") : 0;
  if (j.has("kind")) {
    const std::string kind = j.string("kind");
    if (kind == "verification")
      s.kind = SessionKind::kVerification;
    else if (kind != "calibration")
      throw InputError(std::string(kSessionWhere) + ": kind '" + kind +
                       "' is not calibration or verification");
  }
  s.verifies = j.has("verifies") ? j.string("verifies") : "";
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
  s.config = j.has("config") ? j.at("config") : Json::object();
  return s;
}

}  // namespace zerocal
