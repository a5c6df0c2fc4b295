#include "zerocal/results/holdout_report.h"

#include "vector_json.h"
#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {
namespace {

nlohmann::json toJson(const AimingError& e) {
  return {{"on_psd_mm", {numberOrNull(e.on_psd_mm.x()), numberOrNull(e.on_psd_mm.y())}},
          {"on_psd_norm_mm", numberOrNull(e.on_psd_norm_mm)},
          {"miss_mm", numberOrNull(e.miss_mm)}};
}

AimingError aimingErrorFromJson(const JsonReader& j) {
  AimingError e;
  const std::vector<double> uv = j.numbers("on_psd_mm", 2);
  e.on_psd_mm = {uv[0], uv[1]};
  e.on_psd_norm_mm = j.numberOrNan("on_psd_norm_mm");
  e.miss_mm = j.numberOrNan("miss_mm");
  return e;
}

}  // namespace

nlohmann::json toJson(const HoldoutReport& r) {
  nlohmann::json j;
  j["held_out"] = r.held_out;
  j["total_poses"] = r.total_poses;
  j["nominal_target_mm"] = {r.nominal_target_mm.x(), r.nominal_target_mm.y(),
                            r.nominal_target_mm.z()};
  j["poses"] = nlohmann::json::array();
  for (const HeldOutPose& p : r.poses)
    j["poses"].push_back({{"pose", p.pose},
                          {"line", p.source_line},
                          {"before", toJson(p.before)},
                          {"after", toJson(p.after)}});
  j["rms_before_mm"] = numberOrNull(r.rms_before_mm);
  j["rms_after_mm"] = numberOrNull(r.rms_after_mm);
  return j;
}

HoldoutReport holdoutReportFromJson(const nlohmann::json& json, const std::string& where) {
  const JsonReader j(json, where);
  HoldoutReport r;
  for (const nlohmann::json& pose : j.array("held_out")) {
    if (!pose.is_number_integer()) throw InputError(where + ": 'held_out' is not a pose list");
    r.held_out.push_back(pose.get<int>());
  }
  r.total_poses = j.integer("total_poses");
  r.nominal_target_mm = vector3(j, "nominal_target_mm");
  for (std::size_t i = 0; i < j.array("poses").size(); ++i) {
    const JsonReader p = j.element("poses", i);
    r.poses.push_back({p.integer("pose"), p.integer("line"),
                       aimingErrorFromJson(p.object("before")),
                       aimingErrorFromJson(p.object("after"))});
  }
  r.rms_before_mm = j.numberOrNan("rms_before_mm");
  r.rms_after_mm = j.numberOrNan("rms_after_mm");
  return r;
}

}  // namespace zerocal
