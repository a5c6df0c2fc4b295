#include "zerocal/calib/format.h"

#include <fmt/printf.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {
namespace {

// printf's format, as long as the text is (fmt's sprintf: each argument formatted by its type).
template <typename... Args>
std::string printf(const char* spec, const Args&... args) {
  return fmt::sprintf(spec, args...);
}

}  // namespace

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
  o << printf("noise %.4f mm (%s)", r.noise_mm, noiseText(r).c_str());
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
    for (int l = 0; l < kLinkParameterCount; ++l) {
      if (pr.link_identifiable[l])
        o << printf("  %-19s %10.5f\n", linkParamName(l).c_str(), pr.link_sigma[l]);
      else
        o << printf("  %-19s %s\n", linkParamName(l).c_str(), pr.link_reason[l].c_str());
    }
  }
  o << printf("  RMS over delta2..delta5: %.5f deg; %s %d of %d, condition number %.1f\n",
              pr.rms_offset_sigma_deg, pr.placements > 1 ? "identified" : "rank", pr.rank,
              pr.placements > 1
                  ? kIdentifiedCount + kLinkParameterCount + kTargetCount * pr.placements
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
                     {"predicted_rms_sigma_deg", numberOrNull(r.predicted_rms_sigma_deg)},
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
                       {"crb", numberOrNull(st.crb)},
                       {"std_over_crb", numberOrNull(st.std / st.crb)},
                       {"mean_error_over_crb", numberOrNull(st.mean_error / st.crb)}};
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
                 {"deg_per_20um", numberOrNull(s[i].deg_per_20um)}});
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

}  // namespace zerocal
