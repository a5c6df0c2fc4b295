#include "zerocal/results/plan.h"

#include <cmath>

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"
#include "zerocal/results/placements.h"

namespace zerocal {

nlohmann::json toJson(const Plan& plan) {
  nlohmann::json j;
  j["description"] = plan.description;
  j["candidates_considered"] = plan.candidates_considered;
  j["poses"] = nlohmann::json::array();
  for (const auto& p : plan.poses) j["poses"].push_back(p.q_deg);
  // A parameter the prediction holds nothing for (a plan not predicted) is left out, as
  // planFromJson reads it: "not predicted".
  const Prediction& pr = plan.prediction;
  const auto holds = [](std::size_t k, const auto&... vectors) {
    return ((k < vectors.size()) && ...);
  };
  nlohmann::json pred = nlohmann::json::object();
  for (int k = 0; k < kIdentifiedCount; ++k) {
    if (!holds(k, pr.identifiable, pr.sigma, pr.reason)) continue;
    nlohmann::json e{{"identifiable", plan.prediction.identifiable[k]},
                     {"sigma", numberOrNull(plan.prediction.sigma[k])}};
    if (!plan.prediction.identifiable[k]) e["reason"] = plan.prediction.reason[k];
    pred[unknownName(k)] = e;
  }
  j["predicted"] = pred;
  if (plan.prediction.placements > 1) {
    j["placements"] = plan.prediction.placements;
    j["pose_placements"] = nlohmann::json::array();
    for (const auto& p : plan.poses) j["pose_placements"].push_back(p.placement);
    nlohmann::json links = nlohmann::json::object();
    for (int l = 0; l < kLinkParameterCount; ++l) {
      if (!holds(l, pr.link_identifiable, pr.link_sigma, pr.link_reason)) continue;
      nlohmann::json e{{"identifiable", plan.prediction.link_identifiable[l]},
                       {"sigma", numberOrNull(plan.prediction.link_sigma[l])}};
      if (!plan.prediction.link_identifiable[l]) e["reason"] = plan.prediction.link_reason[l];
      links[linkParamName(l)] = e;
    }
    j["predicted_link_errors"] = links;
  }
  j["predicted_rms_offset_sigma_deg"] = numberOrNull(plan.prediction.rms_offset_sigma_deg);
  if (pr.required_accuracy_deg > 0) j["required_accuracy_deg"] = pr.required_accuracy_deg;
  if (pr.cell_time_sessions > 0)
    j["predicted_cell_time"] = {{"seconds", pr.cell_time_s},
                                {"per_pose_s", pr.cell_time_per_pose_s},
                                {"from_sessions", pr.cell_time_sessions}};
  j["rank"] = plan.prediction.rank;
  j["condition_number"] = numberOrNull(plan.prediction.condition_number);
  return j;
}

Plan planFromJson(const nlohmann::json& json, const std::string& where) {
  const JsonReader j(json, where);
  Plan plan;
  plan.description = j.stringOr("description", "");
  plan.candidates_considered =
      j.has("candidates_considered") ? j.integer("candidates_considered") : 0;
  const nlohmann::json& poses = j.array("poses");
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const std::vector<double> q =
        JsonReader::numbersOf(poses[i], kJointCount, where + " poses[" + std::to_string(i) + "]");
    Pose pose;
    for (int k = 0; k < kJointCount; ++k) {
      if (!std::isfinite(q[k]))
        throw InputError(where + " poses[" + std::to_string(i) + "]: not six finite joint angles");
      pose.q_deg[k] = q[k];
    }
    plan.poses.push_back(pose);
  }
  Prediction& p = plan.prediction;
  p.sigma.assign(kIdentifiedCount, std::nan(""));
  p.identifiable.assign(kIdentifiedCount, false);
  p.reason.assign(kIdentifiedCount, "not predicted");
  p.rms_offset_sigma_deg = std::nan("");
  p.condition_number = std::nan("");
  if (j.present("predicted")) {
    const JsonReader predicted = j.object("predicted");
    for (int k = 0; k < kIdentifiedCount; ++k) {
      const std::string name = unknownName(k);
      if (!predicted.has(name.c_str())) continue;
      const JsonReader e = predicted.object(name.c_str());
      p.identifiable[k] = e.boolean("identifiable");
      p.sigma[k] = e.numberOrNan("sigma");
      p.reason[k] = e.stringOr("reason", "");
    }
    p.rms_offset_sigma_deg = j.numberOrNan("predicted_rms_offset_sigma_deg");
    p.rank = j.has("rank") ? j.integer("rank") : 0;
    p.condition_number = j.numberOrNan("condition_number");
  }
  if (j.present("required_accuracy_deg")) {
    p.required_accuracy_deg = j.numberOrNan("required_accuracy_deg");
    if (!(p.required_accuracy_deg > 0 && p.required_accuracy_deg <= 1))
      throw InputError(where + " required_accuracy_deg: not a number in (0, 1] deg");
  }
  if (j.present("predicted_cell_time")) {
    const JsonReader t = j.object("predicted_cell_time");
    p.cell_time_s = t.number("seconds");
    p.cell_time_per_pose_s = t.number("per_pose_s");
    p.cell_time_sessions = t.integer("from_sessions");
    if (!(p.cell_time_s >= 0 && p.cell_time_per_pose_s >= 0 && p.cell_time_sessions > 0))
      throw InputError(where + " predicted_cell_time: not a time >= 0 from one session or more");
  }
  // A plan at several PSD placements: each pose's placement, and what it predicts of the link
  // errors (toJson writes these only then).
  if (j.present("pose_placements")) {
    const std::vector<double> numbers = JsonReader::numbersOf(
        j.json().at("pose_placements"), plan.poses.size(), where + " pose_placements");
    for (std::size_t i = 0; i < plan.poses.size(); ++i) {
      if (numbers[i] != std::floor(numbers[i]) || numbers[i] < 1 || numbers[i] > kMaxPlacements)
        throw InputError(where + " pose_placements[" + std::to_string(i) +
                         "]: not a placement number 1.." + std::to_string(kMaxPlacements));
      plan.poses[i].placement = static_cast<int>(numbers[i]);
    }
    p.placements = j.has("placements") ? j.integer("placements") : placementCount(plan.poses);
  }
  if (j.present("predicted_link_errors")) {
    const JsonReader links = j.object("predicted_link_errors");
    p.link_sigma.assign(kLinkParameterCount, std::nan(""));
    p.link_identifiable.assign(kLinkParameterCount, false);
    p.link_reason.assign(kLinkParameterCount, "not predicted");
    for (int l = 0; l < kLinkParameterCount; ++l) {
      const std::string name = linkParamName(l);
      if (!links.has(name.c_str())) continue;
      const JsonReader e = links.object(name.c_str());
      p.link_identifiable[l] = e.boolean("identifiable");
      p.link_sigma[l] = e.numberOrNan("sigma");
      p.link_reason[l] = e.stringOr("reason", "");
    }
  }
  return plan;
}

}  // namespace zerocal
