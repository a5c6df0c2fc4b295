#include "zerocal/results/result_file.h"

#include <algorithm>

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {
namespace {

using Json = nlohmann::json;

constexpr const char* kResultWhere = "result.json";

Json toJson(const PoseTimes& p) {
  if (!p.skipped.empty()) return {{"pose", p.pose}, {"skipped", p.skipped}};
  Json j{{"pose", p.pose},
         {"move_s", p.servo.move_s},
         {"acquisition_s", p.servo.acquisition_s},
         {"servo_s", p.servo.servo_s},
         {"settle_s", p.servo.settle_s},
         {"servo_moves", p.servo.moves},
         {"search_moves", p.servo.search_moves},
         {"iterations", p.servo.iterations},
         {"final_error_um", p.servo.final_error_um}};
  if (p.again) j["again"] = true;
  if (p.move_overhead_s) j["move_overhead_s"] = *p.move_overhead_s;
  if (p.fine_point_settle_s) j["fine_point_settle_s"] = *p.fine_point_settle_s;
  return j;
}

PoseTimes poseTimesFromJson(const JsonReader& j) {
  PoseTimes p;
  p.pose = j.integer("pose");
  if (j.has("skipped")) {
    p.skipped = j.string("skipped");
    return p;
  }
  p.servo.move_s = j.number("move_s");
  p.servo.acquisition_s = j.number("acquisition_s");
  p.servo.servo_s = j.number("servo_s");
  p.servo.settle_s = j.number("settle_s");
  p.servo.moves = j.integer("servo_moves");
  p.servo.search_moves = j.has("search_moves") ? j.integer("search_moves") : 0;
  p.servo.iterations = j.integer("iterations");
  p.servo.final_error_um = j.number("final_error_um");
  p.again = j.has("again") && j.boolean("again");
  p.move_overhead_s = j.optionalNumber("move_overhead_s");
  p.fine_point_settle_s = j.optionalNumber("fine_point_settle_s");
  return p;
}

}  // namespace

Json toJson(const ResultFile& r) {
  Json j = toJson(r.report);
  if (!r.verdict_recorded) j.erase("verdict");
  if (r.validation) j["validation"] = toJson(*r.validation);
  if (!r.session.empty()) j["session"] = r.session;
  j["kind"] = sessionKindName(r.kind);
  if (!r.reference.empty()) {
    j["reference"] = r.reference;
    // The offsets of a report against a reference are the change since it, said as such.
    Json change = Json::object();
    for (int k = 0; k < kOffsetCount && k < static_cast<int>(r.report.parameters.size()); ++k) {
      const ParameterEstimate& p = r.report.parameters[static_cast<std::size_t>(k)];
      // As the parameters hold it: an offset not determined has no value.
      change[p.name] = {{"value", p.identifiable ? numberOrNull(p.value) : Json(nullptr)},
                        {"sigma", p.identifiable ? numberOrNull(p.sigma) : Json(nullptr)}};
    }
    j["change"] = change;
  }
  if (r.check) j["check"] = toJson(*r.check);
  if (!r.model_from.empty()) j["model_from"] = r.model_from;
  if (!r.model_file.empty()) j["model_file"] = r.model_file;
  if (!r.reference.empty()) {
    j["drift"] = Json::array();
    for (const Drift& d : r.drift) j["drift"].push_back(toJson(d));
  }
  if (r.cell_time_s) j["cell_time_s"] = *r.cell_time_s;
  if (r.resumed_from) j["resumed_from"] = *r.resumed_from;
  if (r.remeasured) j["remeasured"] = *r.remeasured;
  if (r.cell)
    j["cell"] = {{"controller",
                  {{"robot_type", r.cell->controller.robot_type},
                   {"serial", r.cell->controller.serial},
                   {"software_version", r.cell->controller.software_version}}},
                 {"psd_map", r.cell->psd_map}};
  if (r.cal_offset_rad) j["controller_cal_offset_rad"] = *r.cal_offset_rad;
  if (!r.zerocal_version.empty()) j["zerocal_version"] = r.zerocal_version;
  if (r.finished_unix_s) j["finished_unix_s"] = *r.finished_unix_s;
  if (r.recoveries)
    j["recoveries"] = {{"reconnects", r.recoveries->reconnects},
                       {"reopens", r.recoveries->reopens}};
  if (r.truth) {
    Json truth = Json::object();
    for (int k = 0; k < kOffsetCount; ++k) truth[unknownName(k)] = r.truth->offsets_deg[k];
    if (!r.truth->world_file.empty()) truth["world_file"] = r.truth->world_file;
    if (r.truth->noise_seed) truth["noise_seed"] = *r.truth->noise_seed;
    j["truth"] = truth;
  }
  if (r.pose_breakdown) {
    j["pose_breakdown"] = Json::array();
    for (const PoseTimes& p : *r.pose_breakdown) j["pose_breakdown"].push_back(toJson(p));
  }
  return j;
}

ResultFile resultFileFromJson(const Json& json) {
  const JsonReader j(json, kResultWhere);
  ResultFile r;
  r.report = solveReportFromJson(json, kResultWhere);
  r.verdict_recorded = j.has("verdict");
  if (j.has("validation"))
    r.validation = holdoutReportFromJson(j.at("validation"), "result.json validation");
  r.session = j.has("session") ? j.string("session") : "";
  if (j.has("kind")) r.kind = sessionKindFromName(j.string("kind"), kResultWhere);
  r.reference = j.has("reference") ? j.string("reference") : "";
  r.model_from = j.has("model_from") ? j.string("model_from") : "";
  r.model_file = j.has("model_file") ? j.string("model_file") : "";
  if (j.present("check")) r.check = checkJudgementFromJson(j.at("check"), "result.json check");
  if (j.present("drift"))
    for (std::size_t i = 0; i < j.array("drift").size(); ++i)
      r.drift.push_back(driftFromJson(j.array("drift")[i], "result.json drift"));
  r.cell_time_s = j.optionalNumber("cell_time_s");
  if (j.has("resumed_from")) r.resumed_from = j.integer("resumed_from");
  if (j.has("remeasured")) {
    r.remeasured.emplace();
    for (const Json& pose : j.array("remeasured")) {
      if (!pose.is_number_integer())
        throw InputError("result.json remeasured: not a list of pose numbers");
      r.remeasured->push_back(pose.get<int>());
    }
  }
  if (j.has("cell")) {
    const JsonReader cell = j.object("cell");
    ResultFile::Cell c;
    if (cell.has("controller")) {
      const JsonReader controller = cell.object("controller");
      c.controller.robot_type = controller.stringOr("robot_type", "");
      c.controller.serial = controller.stringOr("serial", "");
      c.controller.software_version = controller.stringOr("software_version", "");
    }
    c.psd_map = cell.stringOr("psd_map", "");
    r.cell = c;
  }
  if (j.has("controller_cal_offset_rad")) {
    const std::vector<double> v = j.numbers("controller_cal_offset_rad", 6);
    r.cal_offset_rad.emplace();
    std::copy(v.begin(), v.end(), r.cal_offset_rad->begin());
  }
  r.zerocal_version = j.stringOr("zerocal_version", "");
  if (j.has("finished_unix_s")) r.finished_unix_s = j.integer64("finished_unix_s");
  if (j.has("recoveries")) {
    const JsonReader rec = j.object("recoveries");
    r.recoveries = ResultFile::Recoveries{rec.integer("reconnects"), rec.integer("reopens")};
  }
  if (j.present("truth")) {
    const JsonReader truth = j.object("truth");
    ResultFile::Truth t;
    for (int k = 0; k < kOffsetCount; ++k)
      t.offsets_deg[k] = truth.numberOrNan(unknownName(k).c_str());
    t.world_file = truth.stringOr("world_file", "");
    if (truth.present("noise_seed")) {
      // A seed is 64 bits unsigned: more than integer64 holds.
      const nlohmann::json& seed = truth.at("noise_seed");
      if (!seed.is_number_unsigned())
        throw InputError(truth.where() + ": 'noise_seed' is not a whole number >= 0");
      t.noise_seed = seed.get<std::uint64_t>();
    }
    r.truth = t;
  }
  if (j.has("pose_breakdown")) {
    r.pose_breakdown.emplace();
    for (std::size_t i = 0; i < j.array("pose_breakdown").size(); ++i)
      r.pose_breakdown->push_back(poseTimesFromJson(j.element("pose_breakdown", i)));
  }
  return r;
}

}  // namespace zerocal
