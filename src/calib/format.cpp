#include "zerocal/calib/format.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <sstream>

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {
namespace {

// JSON has no NaN or infinity: an unknown number is null.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

std::string printf(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string printf(const char* format, ...) {
  char buf[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

}  // namespace

std::string costName(CostKind cost) {
  return cost == CostKind::kMaximumLikelihood ? "ml" : "pairwise";
}

std::string modelName(const SolveReport& r) {
  return r.used_readings ? "hit-point" : "point-to-line";
}

std::string noiseSourceName(const SolveReport& r) {
  return r.noise_estimated ? "estimated from the residuals" : "given";
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
                                  {"chi2_without", number(s.chi2_without)}});
  j["converged"] = r.converged;
  j["message"] = r.message;
  j["cost"] = costName(r.cost);
  j["model"] = modelName(r);
  j["poses"] = r.pose_count;
  j["poses_used"] = r.poses_used;
  j["required_accuracy_deg"] = r.required_accuracy_deg;
  j["model_tolerance"] = {{"length_mm", r.model_length_mm}, {"angle_deg", r.model_angle_deg}};
  if (r.model_sag_deg > 0) j["model_tolerance"]["sag_deg"] = r.model_sag_deg;
  nlohmann::json params = nlohmann::json::object();
  for (const auto& p : r.parameters) {
    nlohmann::json e;
    e["identifiable"] = p.identifiable;
    e["value"] = p.identifiable ? number(p.value) : nlohmann::json();
    e["sigma"] = p.identifiable ? number(p.sigma) : nlohmann::json();
    e["ci95"] =
        p.identifiable ? nlohmann::json{number(p.ci95_low), number(p.ci95_high)} : nlohmann::json();
    if (!p.identifiable) e["reason"] = p.reason;
    if (p.identifiable && p.model_sigma > 0) e["model_sigma"] = number(p.model_sigma);
    if (p.name.rfind("delta", 0) == 0 && p.identifiable) e["value_rad"] = p.value * kDegToRad;
    params[p.name] = e;
  }
  j["parameters"] = params;
  j["not_identifiable"] = nlohmann::json::array();
  for (const auto& n : r.not_identifiable)
    j["not_identifiable"].push_back({{"name", n.name}, {"reason", n.reason}});
  j["target_mm"] = {r.estimate.target_mm.x(), r.estimate.target_mm.y(), r.estimate.target_mm.z()};
  j["target_sigma_mm"] = {number(r.target_sigma_mm.x()), number(r.target_sigma_mm.y()),
                          number(r.target_sigma_mm.z())};
  if (!r.placements.empty()) {
    j["placements"] = nlohmann::json::array();
    for (const auto& c : r.placements)
      j["placements"].push_back({{"placement", c.placement},
                                 {"poses", c.poses},
                                 {"target_mm", {c.target_mm.x(), c.target_mm.y(), c.target_mm.z()}},
                                 {"target_sigma_mm",
                                  {number(c.target_sigma_mm.x()), number(c.target_sigma_mm.y()),
                                   number(c.target_sigma_mm.z())}}});
  }
  j["rank"] = r.rank;
  j["condition_number"] = number(r.condition_number);
  j["dof"] = r.dof;
  j["noise_mm"] = number(r.noise_mm);
  j["noise_source"] = noiseSourceName(r);
  j["chi2_per_dof"] = r.chi2_per_dof ? number(*r.chi2_per_dof) : nlohmann::json();
  j["chi2_p_value"] = r.chi2_p_value ? number(*r.chi2_p_value) : nlohmann::json();
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
         {"normalised", number(p.normalised)},
         {"outlier", p.outlier},
         {"used", p.used},
         {"duplicate_of", p.duplicate_of ? nlohmann::json(p.duplicate_of) : nlohmann::json()},
         {"standoff_mm", p.standoff_mm}});
  }
  nlohmann::json corr = nlohmann::json::array();
  for (int a = 0; a < r.correlation.rows(); ++a) {
    nlohmann::json row = nlohmann::json::array();
    for (int b = 0; b < r.correlation.cols(); ++b) row.push_back(number(r.correlation(a, b)));
    corr.push_back(row);
  }
  j["correlation"] = corr;
  j["iterations"] = r.iterations;
  j["solve_time_ms"] = r.solve_time_ms;
  return j;
}

std::string toText(const Verdict& v) {
  std::ostringstream o;
  o << (v.usable ? "VERDICT: usable\n"
                 : "VERDICT: NOT USABLE - no correction is offered; do not change the robot\n");
  for (const std::string& reason : v.reasons) o << "  - " << reason << "\n";
  return o.str();
}

std::string toText(const SolveReport& r) {
  std::ostringstream o;
  o << toText(r.verdict);
  if (!r.suspect_poses.empty()) o << "suspect poses:\n";
  for (const SuspectPose& s : r.suspect_poses) {
    o << "  pose " << s.pose;
    if (s.source_line) o << " (line " << s.source_line << ")";
    o << ": " << s.reason << printf(" [chi-square per dof without it %.2f]\n", s.chi2_without);
  }
  o << "\n";
  o << "Calibration from " << r.pose_count << " poses, "
    << (r.cost == CostKind::kMaximumLikelihood ? "maximum-likelihood cost, "
                                               : "pairwise (paper eq. 6) cost, ")
    << (r.used_readings ? "hit-point model (PSD readings used)" : "laser aimed at the PSD centre")
    << "\n";
  o << (r.converged ? "converged" : "DID NOT CONVERGE") << " after " << r.iterations
    << " iterations (" << printf("%.2f", r.solve_time_ms) << " ms): " << r.message << "\n";
  if (r.poses_used != r.pose_count)
    o << r.poses_used << " of the " << r.pose_count << " poses used (see the suspect poses)\n";
  o << printf("noise %.4f mm (%s)", r.noise_mm,
              r.noise_estimated ? "estimated from the residuals"
              : r.noise_scale > 1
                  ? printf("given %.4f mm, scaled up by sqrt(chi2/dof) = %.2f: the poses miss "
                           "by more than it",
                           r.noise_mm / r.noise_scale, r.noise_scale)
                        .c_str()
                  : "given");
  if (r.chi2_per_dof)
    o << printf(", chi-square per degree of freedom %.2f (dof %d, p = %.2g)", *r.chi2_per_dof,
                r.dof, r.chi2_p_value.value_or(NAN));
  o << printf("\nrequired accuracy %.4f deg (one sigma of each offset)\n\n",
              r.required_accuracy_deg);
  o << printf("%-19s %12s %10s   %s\n", "parameter", "value", "sigma", "95% interval");
  for (const auto& p : r.parameters) {
    if (!p.identifiable) {
      o << printf("%-19s %12s\n", p.name.c_str(), "not identifiable (see below)");
      continue;
    }
    if (!r.verdict.usable && p.name.rfind("delta", 0) == 0) {
      o << printf("%-19s %12s\n", p.name.c_str(), "withheld: the result is not usable");
      continue;
    }
    o << printf("%-19s %12.5f %10.5f   [%.5f, %.5f]\n", p.name.c_str(), p.value, p.sigma,
                p.ci95_low, p.ci95_high);
  }
  o << "\nNot identifiable from these poses:\n";
  for (const auto& n : r.not_identifiable) o << "  " << n.name << ": " << n.reason << "\n";
  o << printf("\ntarget (PSD centre) %.3f %.3f %.3f mm, sigma %.3f %.3f %.3f mm\n",
              r.estimate.target_mm.x(), r.estimate.target_mm.y(), r.estimate.target_mm.z(),
              r.target_sigma_mm.x(), r.target_sigma_mm.y(), r.target_sigma_mm.z());
  for (const auto& c : r.placements)
    o << printf("placement %d (%d poses): centre %.3f %.3f %.3f mm, sigma %.3f %.3f %.3f mm\n",
                c.placement, c.poses, c.target_mm.x(), c.target_mm.y(), c.target_mm.z(),
                c.target_sigma_mm.x(), c.target_sigma_mm.y(), c.target_sigma_mm.z());
  if (!r.placements.empty())
    o << "identified " << r.rank << " of "
      << r.parameters.size() + kTargetCount * r.placements.size()
      << " unknowns (the others are named above), condition number "
      << printf("%.1f", r.condition_number) << " (column-scaled Jacobian)\n";
  else
    o << "rank " << r.rank << " of " << kUnknownCount << ", condition number "
      << printf("%.1f", r.condition_number) << " (column-scaled Jacobian)\n";
  std::string strong;
  for (int a = 0; a < r.correlation.rows(); ++a)
    for (int b = a + 1; b < r.correlation.cols(); ++b)
      if (std::abs(r.correlation(a, b)) > 0.9)
        strong += printf("  %s ~ %s: %+.3f\n", unknownName(a).c_str(), unknownName(b).c_str(),
                         r.correlation(a, b));
  if (!strong.empty()) o << "strong correlations (|r| > 0.9):\n" << strong;
  o << printf("\n%5s %6s %10s %10s %11s %12s\n", "pose", "line", "miss_mm", "normalised",
              "standoff_mm", "");
  for (std::size_t i = 0; i < r.poses.size(); ++i) {
    const auto& p = r.poses[i];
    o << printf("%5zu %6d %10.4f %10.2f %11.1f %12s\n", i + 1, p.source_line, p.miss_norm_mm,
                p.normalised, p.standoff_mm,
                p.outlier        ? "LEFT OUT"
                : p.duplicate_of ? "DUPLICATE"
                                 : "");
  }
  o << printf("RMS miss %.4f mm\n", r.rms_miss_mm);
  return o.str();
}

namespace {

nlohmann::json toJson(const AimingError& e) {
  return {{"on_psd_mm", {number(e.on_psd_mm.x()), number(e.on_psd_mm.y())}},
          {"on_psd_norm_mm", number(e.on_psd_norm_mm)},
          {"miss_mm", number(e.miss_mm)}};
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
  j["rms_before_mm"] = number(r.rms_before_mm);
  j["rms_after_mm"] = number(r.rms_after_mm);
  return j;
}

std::string toText(const HoldoutReport& r) {
  std::ostringstream o;
  o << "\nValidation: " << r.poses.size() << " of " << r.total_poses
    << " poses held out of the solve; aiming error at the PSD (predicted spot - measured spot on "
       "the PSD plane)\nbefore: nominal model (zero offsets, nominal laser, its own best target); "
       "after: the identified parameters\n";
  o << printf("%5s %6s %12s %12s %14s %14s\n", "pose", "line", "before_mm", "after_mm",
              "after_u_mm", "after_v_mm");
  for (const HeldOutPose& p : r.poses)
    o << printf("%5d %6d %12.4f %12.4f %+14.4f %+14.4f\n", p.pose, p.source_line,
                p.before.on_psd_norm_mm, p.after.on_psd_norm_mm, p.after.on_psd_mm.x(),
                p.after.on_psd_mm.y());
  o << printf("RMS before %.4f mm, after %.4f mm\n", r.rms_before_mm, r.rms_after_mm);
  return o.str();
}

nlohmann::json toJson(const Plan& plan) {
  nlohmann::json j;
  j["description"] = plan.description;
  j["candidates_considered"] = plan.candidates_considered;
  j["poses"] = nlohmann::json::array();
  for (const auto& p : plan.poses) j["poses"].push_back(p.q_deg);
  nlohmann::json pred;
  for (int k = 0; k < kIdentifiedCount; ++k) {
    nlohmann::json e{{"identifiable", plan.prediction.identifiable[k]},
                     {"sigma", number(plan.prediction.sigma[k])}};
    if (!plan.prediction.identifiable[k]) e["reason"] = plan.prediction.reason[k];
    pred[unknownName(k)] = e;
  }
  j["predicted"] = pred;
  if (plan.prediction.placements > 1) {
    j["placements"] = plan.prediction.placements;
    j["pose_placements"] = nlohmann::json::array();
    for (const auto& p : plan.poses) j["pose_placements"].push_back(p.placement);
    nlohmann::json links = nlohmann::json::object();
    for (int l = 0; l < kLinkParamCount; ++l) {
      nlohmann::json e{{"identifiable", plan.prediction.link_identifiable[l]},
                       {"sigma", number(plan.prediction.link_sigma[l])}};
      if (!plan.prediction.link_identifiable[l]) e["reason"] = plan.prediction.link_reason[l];
      links[linkParamName(l)] = e;
    }
    j["predicted_link_errors"] = links;
  }
  j["predicted_rms_offset_sigma_deg"] = number(plan.prediction.rms_offset_sigma_deg);
  j["rank"] = plan.prediction.rank;
  j["condition_number"] = number(plan.prediction.condition_number);
  return j;
}

std::string toText(const Plan& plan) {
  std::ostringstream o;
  o << plan.description << "\n";
  o << "predicted one-sigma uncertainty before any move:\n";
  for (int k = 0; k < kIdentifiedCount; ++k) {
    if (plan.prediction.identifiable[k])
      o << printf("  %-19s %10.5f\n", unknownName(k).c_str(), plan.prediction.sigma[k]);
    else
      o << printf("  %-19s not identifiable: %s\n", unknownName(k).c_str(),
                  plan.prediction.reason[k].c_str());
  }
  const Prediction& pr = plan.prediction;
  if (pr.placements > 1) {
    o << "link errors (" << pr.placements << " placements):\n";
    for (int l = 0; l < kLinkParamCount; ++l) {
      if (pr.link_identifiable[l])
        o << printf("  %-19s %10.5f\n", linkParamName(l).c_str(), pr.link_sigma[l]);
      else
        o << printf("  %-19s %s\n", linkParamName(l).c_str(), pr.link_reason[l].c_str());
    }
  }
  o << printf("  RMS over delta2..delta5: %.5f deg; %s %d of %d, condition number %.1f\n",
              pr.rms_offset_sigma_deg, pr.placements > 1 ? "identified" : "rank", pr.rank,
              pr.placements > 1 ? kIdentifiedCount + kLinkParamCount + kTargetCount * pr.placements
                                : kUnknownCount,
              pr.condition_number);
  return o.str();
}

nlohmann::json toJson(const std::vector<ScenarioResult>& results,
                      const ExperimentOptions& options) {
  nlohmann::json j;
  j["experiment"] = "table2";
  j["repeats"] = options.repeats;
  j["seed"] = options.seed;
  j["scenarios"] = nlohmann::json::array();
  for (const auto& r : results) {
    nlohmann::json s{{"pattern", patternName(r.pattern)},
                     {"cost", costName(r.cost)},
                     {"rms_error_deg", r.rms_error_deg},
                     {"predicted_rms_sigma_deg", number(r.predicted_rms_sigma_deg)},
                     {"not_identifiable_runs", r.not_identifiable_runs},
                     {"failed_runs", r.failed_runs},
                     {"mean_solve_ms", r.mean_solve_ms}};
    s["poses"] = nlohmann::json::array();
    for (const auto& p : r.poses) s["poses"].push_back(p.q_deg);
    s["parameters"] = nlohmann::json::object();
    for (const auto& st : r.stats) {
      nlohmann::json e{{"truth", st.truth},
                       {"mean_error", st.mean_error},
                       {"std", st.std},
                       {"crb", number(st.crb)},
                       {"std_over_crb", number(st.std / st.crb)},
                       {"mean_error_over_crb", number(st.mean_error / st.crb)}};
      if (st.has_paper) e["paper"] = {{"mean_error", st.paper_mean_error}, {"std", st.paper_std}};
      s["parameters"][st.name] = e;
    }
    j["scenarios"].push_back(s);
  }
  return j;
}

std::string toText(const std::vector<ScenarioResult>& results, const ExperimentOptions& options) {
  std::ostringstream o;
  o << "Table II scenario (IRB1600, P1 = (900, -50, 400) mm, uniform +-0.05 mm localisation "
       "error, 8 poses), "
    << options.repeats << " repeats, seed " << options.seed << "\n";
  o << "errors = estimate - truth; offsets in deg; CRB = Cramer-Rao bound (one sigma) at the "
       "truth\n";
  for (const auto& r : results) {
    o << "\n== pattern " << patternName(r.pattern) << ", " << costName(r.cost)
      << " cost: RMS error " << printf("%.5f", r.rms_error_deg) << " deg over delta2..5 (predicted "
      << printf("%.5f", r.predicted_rms_sigma_deg) << "), " << r.not_identifiable_runs
      << " runs flagged an offset not identifiable, " << r.failed_runs
      << " did not converge, mean solve " << printf("%.2f", r.mean_solve_ms) << " ms\n";
    o << printf("%-19s %9s %11s %10s %10s %8s %8s  %s\n", "parameter", "truth", "mean err", "STD",
                "CRB", "STD/CRB", "mean/CRB", "paper mean err, STD");
    for (const auto& st : r.stats) {
      o << printf("%-19s %9.4f %11.6f %10.6f %10.6f %8.3f %8.3f", st.name.c_str(), st.truth,
                  st.mean_error, st.std, st.crb, st.std / st.crb, st.mean_error / st.crb);
      if (st.has_paper) o << printf("  %.6f, %.6f", st.paper_mean_error, st.paper_std);
      o << "\n";
    }
  }
  return o.str();
}

nlohmann::json toJson(const std::array<JointSensitivity, kJointCount>& s) {
  nlohmann::json j = nlohmann::json::array();
  for (int i = 0; i < kJointCount; ++i)
    j.push_back({{"joint", i + 1},
                 {"spot_mm_per_deg", {s[i].spot_mm_per_deg.x(), s[i].spot_mm_per_deg.y()}},
                 {"magnitude_mm_per_deg", s[i].magnitude_mm_per_deg},
                 {"deg_per_20um", number(s[i].deg_per_20um)}});
  return j;
}

std::string toText(const std::array<JointSensitivity, kJointCount>& s) {
  std::ostringstream o;
  o << printf("%5s %12s %12s %14s %14s\n", "joint", "du mm/deg", "dv mm/deg", "|d| mm/deg",
              "deg per 20 um");
  for (int i = 0; i < kJointCount; ++i)
    o << printf("%5d %12.4f %12.4f %14.4f %14.6f\n", i + 1, s[i].spot_mm_per_deg.x(),
                s[i].spot_mm_per_deg.y(), s[i].magnitude_mm_per_deg, s[i].deg_per_20um);
  return o.str();
}

namespace {

Eigen::Vector3d vector3(const JsonReader& j, const char* key) {
  const std::vector<double> v = j.numbers(key, 3);
  return {v[0], v[1], v[2]};
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
    r.model_sag_deg = m.has("sag_deg") ? m.number("sag_deg") : 0;
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
    for (int l = 0; l < kLinkParamCount; ++l)  // several placements: a, d in mm, alpha in deg
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
    p.link_sigma.assign(kLinkParamCount, std::nan(""));
    p.link_identifiable.assign(kLinkParamCount, false);
    p.link_reason.assign(kLinkParamCount, "not predicted");
    for (int l = 0; l < kLinkParamCount; ++l) {
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
