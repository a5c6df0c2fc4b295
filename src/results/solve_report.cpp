#include "zerocal/results/solve_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "vector_json.h"
#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {

std::string costName(CostKind cost) {
  return cost == CostKind::kMaximumLikelihood ? "ml" : "pairwise";
}

std::string modelName(const SolveReport& r) {
  return r.used_readings ? "hit-point" : "point-to-line";
}

std::string noiseSourceName(const SolveReport& r) {
  return r.noise_estimated               ? "estimated from the residuals"
         : r.joint_repeatability_deg > 0 ? "per pose, from the joints' repeatability"
                                         : "given";
}

std::string noiseText(const SolveReport& r) {
  if (r.noise_estimated) return "estimated from the residuals";
  const char* given = r.joint_repeatability_deg > 0 ? "the per-pose model's reference" : "given";
  if (r.noise_scale > 1) {
    // With the link tolerances counted the chi-square is of the misses they do not explain: the
    // noise or the links are worse than stated, and both parts of each sigma grow by the ratio.
    const bool links = r.model_calibrated || r.model_length_mm > 0 || r.model_angle_deg > 0;
    return fmt::format("{} {:.4f} mm, scaled up by sqrt(chi2/dof) = {:.2f}: {}", given,
                       r.noise_mm / r.noise_scale, r.noise_scale,
                       links ? "the poses miss by more than it and the robot file's link "
                               "tolerances allow together (the noise, or the links, are worse "
                               "than stated); both parts of each sigma are scaled"
                             : "the poses miss by more than it");
  }
  if (r.joint_repeatability_deg > 0)
    return fmt::format(
        "the reference of the per-pose model: {:.4f} deg joint repeatability, each pose weighed "
        "by its own covariance",
        r.joint_repeatability_deg);
  return "given";
}

nlohmann::json toJson(const Verdict& v) { return {{"usable", v.usable}, {"reasons", v.reasons}}; }

nlohmann::json toJson(const SolveReport& r) {
  nlohmann::json j;
  j["verdict"] = toJson(r.verdict);
  j["suspect_poses"] = nlohmann::json::array();
  for (const SuspectPose& s : r.suspect_poses)
    j["suspect_poses"].push_back({{"pose", s.pose},
                                  {"line", s.source_line},
                                  {"reason", s.reason},
                                  {"chi2_without", numberOrNull(s.chi2_without)}});
  j["converged"] = r.converged;
  j["message"] = r.message;
  j["cost"] = costName(r.cost);
  j["model"] = modelName(r);
  j["poses"] = r.pose_count;
  j["poses_used"] = r.poses_used;
  j["required_accuracy_deg"] = r.required_accuracy_deg;
  j["model_tolerance"] = {{"length_mm", r.model_length_mm}, {"angle_deg", r.model_angle_deg}};
  if (anyCounted(r.model_sag_deg))
    j["model_tolerance"]["sag_deg"] = r.model_sag_deg;  // joints 2 and 3
  if (anyCounted(r.model_sag_mean_deg)) j["model_tolerance"]["sag_mean_deg"] = r.model_sag_mean_deg;
  if (r.model_calibrated) j["model_tolerance"]["calibrated"] = true;
  nlohmann::json params = nlohmann::json::object();
  for (const auto& p : r.parameters) {
    nlohmann::json e;
    e["identifiable"] = p.identifiable;
    e["value"] = p.identifiable ? numberOrNull(p.value) : nlohmann::json();
    e["sigma"] = p.identifiable ? numberOrNull(p.sigma) : nlohmann::json();
    e["ci95"] = p.identifiable ? nlohmann::json{numberOrNull(p.ci95_low), numberOrNull(p.ci95_high)}
                               : nlohmann::json();
    if (!p.identifiable) e["reason"] = p.reason;
    if (p.identifiable && p.model_sigma > 0) e["model_sigma"] = numberOrNull(p.model_sigma);
    if (p.name.rfind("delta", 0) == 0 && p.identifiable) e["value_rad"] = p.value * kDegToRad;
    params[p.name] = e;
  }
  j["parameters"] = params;
  j["not_identifiable"] = nlohmann::json::array();
  for (const auto& n : r.not_identifiable)
    j["not_identifiable"].push_back({{"name", n.name}, {"reason", n.reason}});
  j["target_mm"] = {r.estimate.target_mm.x(), r.estimate.target_mm.y(), r.estimate.target_mm.z()};
  j["target_sigma_mm"] = {numberOrNull(r.target_sigma_mm.x()), numberOrNull(r.target_sigma_mm.y()),
                          numberOrNull(r.target_sigma_mm.z())};
  if (!r.placements.empty()) {
    j["placements"] = nlohmann::json::array();
    for (const auto& c : r.placements)
      j["placements"].push_back(
          {{"placement", c.placement},
           {"poses", c.poses},
           {"target_mm", {c.target_mm.x(), c.target_mm.y(), c.target_mm.z()}},
           {"target_sigma_mm",
            {numberOrNull(c.target_sigma_mm.x()), numberOrNull(c.target_sigma_mm.y()),
             numberOrNull(c.target_sigma_mm.z())}}});
  }
  j["rank"] = r.rank;
  j["condition_number"] = numberOrNull(r.condition_number);
  j["dof"] = r.dof;
  j["noise_mm"] = numberOrNull(r.noise_mm);
  j["noise_source"] = noiseSourceName(r);
  if (r.joint_repeatability_deg > 0) j["joint_repeatability_deg"] = r.joint_repeatability_deg;
  j["chi2_per_dof"] = r.chi2_per_dof ? numberOrNull(*r.chi2_per_dof) : nlohmann::json();
  j["chi2_p_value"] = r.chi2_p_value ? numberOrNull(*r.chi2_p_value) : nlohmann::json();
  j["noise_scale"] = r.noise_scale;
  j["rms_miss_mm"] = r.rms_miss_mm;
  j["residuals_mm"] = nlohmann::json::array();
  j["pose_residuals"] = nlohmann::json::array();
  for (std::size_t i = 0; i < r.poses.size(); ++i) {
    const auto& p = r.poses[i];
    j["residuals_mm"].push_back(p.miss_norm_mm);
    j["pose_residuals"].push_back(
        {{"pose", i + 1},
         {"line", p.source_line},
         {"miss_mm", {p.miss_mm.x(), p.miss_mm.y()}},
         {"normalised", numberOrNull(p.normalised)},
         {"outlier", p.outlier},
         {"used", p.used},
         {"duplicate_of", p.duplicate_of ? nlohmann::json(p.duplicate_of) : nlohmann::json()},
         {"standoff_mm", p.standoff_mm}});
  }
  nlohmann::json corr = nlohmann::json::array();
  for (int a = 0; a < r.correlation.rows(); ++a) {
    nlohmann::json row = nlohmann::json::array();
    for (int b = 0; b < r.correlation.cols(); ++b) row.push_back(numberOrNull(r.correlation(a, b)));
    corr.push_back(row);
  }
  j["correlation"] = corr;
  j["iterations"] = r.iterations;
  j["solve_time_ms"] = r.solve_time_ms;
  return j;
}

SolveReport solveReportFromJson(const nlohmann::json& json, const std::string& where) {
  const JsonReader j(json, where);
  SolveReport r;
  if (j.has("verdict")) {
    const JsonReader v = j.object("verdict");
    r.verdict.usable = v.boolean("usable");
    for (const nlohmann::json& reason : v.array("reasons")) {
      if (!reason.is_string()) throw InputError(v.where() + ": 'reasons' are not all text");
      r.verdict.reasons.push_back(reason.get<std::string>());
    }
  }
  if (j.has("suspect_poses"))
    for (std::size_t i = 0; i < j.array("suspect_poses").size(); ++i) {
      const JsonReader e = j.element("suspect_poses", i);
      r.suspect_poses.push_back({e.integer("pose"), e.integer("line"), e.string("reason"),
                                 e.numberOrNan("chi2_without")});
    }
  r.converged = j.boolean("converged");
  r.message = j.stringOr("message", "");
  r.cost =
      j.stringOr("cost", "ml") == "pairwise" ? CostKind::kPairwise : CostKind::kMaximumLikelihood;
  r.used_readings = j.stringOr("model", "") == "hit-point";
  r.pose_count = j.integer("poses");
  r.poses_used = j.has("poses_used") ? j.integer("poses_used") : r.pose_count;
  r.required_accuracy_deg = j.has("required_accuracy_deg") ? j.number("required_accuracy_deg") : 0;
  if (j.has("model_tolerance")) {
    const JsonReader m = j.object("model_tolerance");
    r.model_length_mm = m.number("length_mm");
    r.model_angle_deg = m.number("angle_deg");
    // Joints 2 and 3; a result written before they were told apart holds one for both.
    if (m.has("sag_deg"))
      r.model_sag_deg =
          sagTolerancesOf(m.at("sag_deg").is_number() ? std::vector<double>{m.number("sag_deg")}
                                                      : m.numbers("sag_deg", kComplianceCount));
    if (m.has("sag_mean_deg"))
      r.model_sag_mean_deg = sagTolerancesOf(m.numbers("sag_mean_deg", kComplianceCount));
    r.model_calibrated = m.has("calibrated") && m.boolean("calibrated");
  }
  const nlohmann::json& params = j.at("parameters");
  if (!params.is_object()) throw InputError(where + ": 'parameters' is not an object");
  // The solver's order (offsets, then the laser), not JSON's alphabetical one; names this version
  // does not know follow.
  std::vector<std::string> names;
  for (int k = 0; k < kIdentifiedCount; ++k)
    if (params.contains(unknownName(k))) names.push_back(unknownName(k));
  for (const auto& item : params.items())
    if (std::find(names.begin(), names.end(), item.key()) == names.end())
      names.push_back(item.key());
  for (const std::string& name : names) {
    const JsonReader p(params.at(name), where + " parameters." + name);
    ParameterEstimate e;
    e.name = name;
    e.identifiable = p.boolean("identifiable");
    e.reason = p.stringOr("reason", "");
    e.value = p.numberOrNan("value");
    e.sigma = p.numberOrNan("sigma");
    e.model_sigma = p.has("model_sigma") ? p.number("model_sigma") : 0;
    e.ci95_low = e.ci95_high = std::nan("");
    if (p.present("ci95")) {
      const std::vector<double> ci = p.numbers("ci95", 2);
      e.ci95_low = ci[0];
      e.ci95_high = ci[1];
    }
    for (int k = 0; k < kIdentifiedCount; ++k) {
      if (unknownName(k) != name || !e.identifiable) continue;
      if (k < kOffsetCount)
        r.estimate.delta_rad[k] = e.value * kDegToRad;
      else
        r.estimate.laser[k - kOffsetCount] = e.value;
    }
    for (int l = 0; l < kLinkParameterCount; ++l)  // several placements: a, d in mm, alpha in deg
      if (linkParamName(l) == name && e.identifiable)
        r.estimate.link[l] = l % 3 == 2 ? e.value * kDegToRad : e.value;
    r.parameters.push_back(e);
  }
  for (std::size_t i = 0; i < j.array("not_identifiable").size(); ++i) {
    const JsonReader e = j.element("not_identifiable", i);
    r.not_identifiable.push_back({e.string("name"), e.string("reason")});
  }
  r.estimate.target_mm = vector3(j, "target_mm");
  r.target_sigma_mm = vector3(j, "target_sigma_mm");
  if (j.has("placements"))
    for (std::size_t i = 0; i < j.array("placements").size(); ++i) {
      const JsonReader e = j.element("placements", i);
      r.placements.push_back({e.integer("placement"), e.integer("poses"), vector3(e, "target_mm"),
                              vector3(e, "target_sigma_mm")});
    }
  r.rank = j.integer("rank");
  r.condition_number = j.numberOrNan("condition_number");
  r.dof = j.integer("dof");
  r.noise_mm = j.numberOrNan("noise_mm");
  r.noise_estimated = j.stringOr("noise_source", "") == "estimated from the residuals";
  r.joint_repeatability_deg =
      j.has("joint_repeatability_deg") ? j.number("joint_repeatability_deg") : 0;
  r.chi2_per_dof = j.optionalNumber("chi2_per_dof");
  r.chi2_p_value = j.optionalNumber("chi2_p_value");
  r.noise_scale = j.has("noise_scale") ? j.number("noise_scale") : 1;
  r.rms_miss_mm = j.numberOrNan("rms_miss_mm");
  const nlohmann::json& residuals = j.array("pose_residuals");
  for (std::size_t i = 0; i < residuals.size(); ++i) {
    const JsonReader p = j.element("pose_residuals", i);
    PoseResidual pose;
    pose.source_line = p.integer("line");
    pose.used = p.has("used") ? p.boolean("used") : true;
    pose.duplicate_of = p.present("duplicate_of") ? p.integer("duplicate_of") : 0;
    const std::vector<double> miss = p.numbers("miss_mm", 2);
    pose.miss_mm = {miss[0], miss[1]};
    pose.miss_norm_mm = pose.miss_mm.norm();
    pose.normalised = p.numberOrNan("normalised");
    pose.outlier = p.boolean("outlier");
    pose.standoff_mm = p.numberOrNan("standoff_mm");
    r.poses.push_back(pose);
  }
  // The norms as written: the list beside the residuals is what toJson gives back.
  if (j.has("residuals_mm")) {
    const std::vector<double> norms =
        JsonReader::numbersOf(j.at("residuals_mm"), r.poses.size(), where + " residuals_mm");
    for (std::size_t i = 0; i < r.poses.size(); ++i) r.poses[i].miss_norm_mm = norms[i];
  }
  if (j.has("correlation")) {
    const nlohmann::json& rows = j.array("correlation");
    r.correlation.resize(static_cast<Eigen::Index>(rows.size()),
                         static_cast<Eigen::Index>(rows.size()));
    for (std::size_t a = 0; a < rows.size(); ++a) {
      const std::vector<double> row = JsonReader::numbersOf(
          rows[a], rows.size(), where + " correlation row " + std::to_string(a + 1));
      for (std::size_t b = 0; b < rows.size(); ++b)
        r.correlation(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = row[b];
    }
  }
  r.iterations = j.has("iterations") ? j.integer("iterations") : 0;
  r.solve_time_ms = j.has("solve_time_ms") ? j.number("solve_time_ms") : 0;
  return r;
}

}  // namespace zerocal
