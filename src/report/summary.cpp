// summary.txt: what a technician reads first, in 100 columns of plain text.
#include <cmath>
#include <sstream>

#include "content.h"

namespace zerocal::report {

using detail::format;
using detail::num;

std::string summaryText(const SessionReport& r) {
  constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
  std::ostringstream o;
  o << "zerocal calibration summary, session " << r.session.id
    << (r.simulated() ? " (SIMULATED cell: the truth is known)" : "") << "\n";
  o << detail::wrap(detail::verdict(r), 100, 0);
  for (const SuspectPose& sp : r.solve().suspect_poses)
    o << detail::wrap(format("Suspect pose %d (line %d): ", sp.pose, sp.source_line) + sp.reason,
                      100, 2);
  if (!r.remeasured().empty()) o << detail::wrap(detail::remeasuredNote(r), 100, 0);
  for (const std::string& line : detail::identity(r)) o << detail::wrap(line, 100, 0);
  if (!r.session.plan.description.empty())
    o << detail::wrap("plan: " + r.session.plan.description, 100, 0);
  std::string fit =
      format("Solved from %d poses (%s model, %s cost); noise %s mm (%s); ", r.solve().pose_count,
             modelName(r.solve()).c_str(), costName(r.solve().cost).c_str(),
             num("%.4f", r.solve().noise_mm).c_str(), noiseText(r.solve()).c_str());
  if (r.solve().chi2_per_dof)
    fit += format("chi-square per degree of freedom %.2f, dof %d; ", *r.solve().chi2_per_dof,
                  r.solve().dof);
  else
    fit += format("dof %d (chi-square needs a given noise level); ", r.solve().dof);
  fit += format("RMS miss %.1f um; %s, condition number %s.", r.solve().rms_miss_mm * 1000,
                detail::rankText(r).c_str(), num("%.1f", r.solve().condition_number).c_str());
  o << detail::wrap(fit, 100, 0);

  o << "\nJoint offsets, ARM side (joint angle, not motor angle): the true joint angle is the\n"
       "controller's angle plus delta. 95% interval = value +- t * sigma.\n";
  o << format("%-7s %12s %13s %11s %12s   %-25s", "offset", "value deg", "value rad", "sigma deg",
              "sigma rad", "95% interval deg");
  if (r.simulated()) o << format(" %10s", "truth deg");
  o << "\n";
  for (const ParameterRow& p : r.parameters) {
    if (!detail::isOffset(p)) continue;
    const std::string name = p.name.substr(0, 6);
    if (!p.identifiable || detail::refused(r)) {
      o << format(
          "%-7s %s\n", name.c_str(),
          p.identifiable ? "withheld: the result is not usable" : "NOT IDENTIFIABLE (see below)");
      continue;
    }
    o << format("%-7s %+12.5f %+13.7f %11.5f %12.7f   [%+.5f, %+.5f]", name.c_str(), p.value,
                p.value * kDegToRad, p.sigma, p.sigma * kDegToRad, p.ci95_low, p.ci95_high);
    if (p.truth) o << format("  %+10.5f", *p.truth);
    o << "\n";
  }

  o << "\nNot identifiable, and why:\n";
  for (const auto& n : r.solve().not_identifiable) {
    o << "  " << n.name << ":\n" << detail::wrap(n.reason, 100, 4);
  }

  const auto rows = [&](bool laser) {
    for (const ParameterRow& p : r.parameters) {
      if (detail::isOffset(p) || detail::isLaser(p) != laser) continue;
      const std::string unit = detail::unitOf(p.name);
      if (!p.identifiable)
        o << format("  %-18s not identifiable\n", p.name.c_str());
      else
        o << format("  %-18s %+.6g %s (sigma %.3g)\n", p.name.c_str(), p.value, unit.c_str(),
                    p.sigma);
    }
  };
  o << "\nLaser line on the flange (identified with the offsets):\n";
  rows(true);
  const std::vector<std::string> centres = detail::placementCentres(r);
  if (centres.empty()) {
    o << format("PSD centre in the base frame: %.3f %.3f %.3f mm (sigma %s %s %s mm)\n",
                r.solve().estimate.target_mm[0], r.solve().estimate.target_mm[1],
                r.solve().estimate.target_mm[2], num("%.3f", r.solve().target_sigma_mm[0]).c_str(),
                num("%.3f", r.solve().target_sigma_mm[1]).c_str(),
                num("%.3f", r.solve().target_sigma_mm[2]).c_str());
  } else {
    for (const std::string& c : centres) o << detail::wrap(c, 100, 0);
    o << "\n"
      << detail::wrap(
             "Link errors of the arm (lengths in mm, twists in deg), identified with the "
             "offsets from the several PSD placements; the rest are named above:",
             100, 0);
    rows(false);
  }

  o << (detail::linksWeighMisses(r)
            ? "\nWorst poses (normalised miss: in noise sigmas, the link tolerances counted; "
              "SUSPECT: did not fit):\n"
            : "\nWorst poses (normalised miss: in the given noise's sigmas; SUSPECT: did not fit "
              "the others):\n");
  o << format("  %5s %10s %11s %12s\n", "pose", "miss um", "normalised", "standoff mm");
  for (const PoseRow* p : detail::worstPoses(r))
    o << format("  %5d %10.1f %11.2f %12.1f%s\n", p->pose, p->miss_um, p->normalised,
                p->standoff_mm, p->outlier ? "  SUSPECT" : "");

  o << "\nPredicted (plan, before any move) versus achieved one-sigma uncertainty:\n";
  if (const std::string note = detail::toleranceNote(r); !note.empty())
    o << detail::wrap(note, 100, 2);
  for (const ParameterRow& p : r.parameters) {
    const std::string unit = detail::unitOf(p.name);
    o << format("  %-18s predicted %s, achieved %s %s", p.name.c_str(),
                p.predicted_sigma ? num("%.3g", *p.predicted_sigma).c_str() : "n/a",
                p.identifiable ? num("%.3g", p.sigma).c_str() : "n/a", unit.c_str());
    if (p.predicted_sigma && p.identifiable && *p.predicted_sigma > 0)
      o << format(" (ratio %.2f)", p.sigma / *p.predicted_sigma);
    o << "\n";
  }

  o << "\nValidation on held-out poses (aiming error at the PSD, spot distance on its plane):\n";
  if (!r.result.validation) {
    o << "  no poses were held out of this solve (zerocal-lab solve --holdout K does it).\n";
  } else {
    o << format("  %5s %14s %14s %16s\n", "pose", "before mm", "after mm", "after miss mm");
    for (const HeldOutPose& h : r.result.validation->poses)
      o << format("  %5d %14.4f %14.4f %16.4f\n", h.pose, h.before.on_psd_norm_mm,
                  h.after.on_psd_norm_mm, h.after.miss_mm);
    o << format("  RMS: before (nominal model) %.4f mm, after calibration %.4f mm\n",
                r.result.validation->rms_before_mm, r.result.validation->rms_after_mm);
  }

  const detail::Section abb = detail::controllerSection(r);
  o << "\n" << abb.heading << "\n";
  for (const std::string& p : abb.paragraphs) o << detail::wrap(p, 100, 2) << "\n";
  const detail::Section applied = detail::applySection(r);
  if (!applied.heading.empty()) {
    o << "\n" << applied.heading << "\n";
    for (const std::string& p : applied.paragraphs) o << detail::wrap(p, 100, 2);
  }
  if (r.result.cell_time_s) o << format("cell time %.1f s\n", *r.result.cell_time_s);
  o << "report.html beside this file has the plots.\n";
  return o.str();
}

}  // namespace zerocal::report
