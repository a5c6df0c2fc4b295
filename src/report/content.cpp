#include "content.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <sstream>

namespace zerocal::report::detail {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

}  // namespace

std::string num(const char* fmt, double v) { return std::isfinite(v) ? format(fmt, v) : "n/a"; }

bool isOffset(const ParameterRow& p) { return p.name.rfind("delta", 0) == 0; }

bool isLaser(const ParameterRow& p) { return p.name.rfind("laser_", 0) == 0; }

std::string rankText(const SessionReport& r) {
  const SolveReport& s = r.solve();
  if (s.placements.size() < 2) return format("rank %d of 11", s.rank);
  // Offsets, laser, link errors (the parameters), and three coordinates per placement's centre.
  const int unknowns =
      static_cast<int>(s.parameters.size()) + 3 * static_cast<int>(s.placements.size());
  return format("%d of %d unknowns identified (offsets, laser line, %zu PSD centres, link errors)",
                s.rank, unknowns, s.placements.size());
}

std::vector<std::string> placementCentres(const SessionReport& r) {
  std::vector<std::string> out;
  const SolveReport& s = r.solve();
  if (s.placements.size() < 2) return out;
  for (const SolveReport::PlacementCentre& c : s.placements)
    out.push_back(format(
        "PSD centre at placement %d (%d poses): %.3f %.3f %.3f mm in the base "
        "frame (sigma %s %s %s mm)",
        c.placement, c.poses, c.target_mm.x(), c.target_mm.y(), c.target_mm.z(),
        num("%.3f", c.target_sigma_mm.x()).c_str(), num("%.3f", c.target_sigma_mm.y()).c_str(),
        num("%.3f", c.target_sigma_mm.z()).c_str()));
  return out;
}

bool linksWeighMisses(const SessionReport& r) {
  const SolveReport& s = r.solve();
  return s.placements.size() < 2 && !s.noise_estimated &&
         (s.model_calibrated || s.model_length_mm > 0 || s.model_angle_deg > 0 ||
          anyCounted(s.model_sag_deg));
}

std::string toleranceNote(const SessionReport& r) {
  const SolveReport& s = r.solve();
  std::string counted;
  if (s.model_calibrated)
    counted = s.placements.size() < 2
                  ? "the calibrated robot model's link covariance" +
                        (r.result.model_from.empty()
                             ? std::string()
                             : " (the model calibration " + r.result.model_from + " wrote)")
                  : "the calibrated robot model's uncertainty of the link errors these poses do "
                    "not identify";
  else if (s.model_length_mm > 0 || s.model_angle_deg > 0)
    counted = format(s.placements.size() < 2
                         ? "the robot's link tolerances (%.3g mm, %.3g deg)"
                         : "the tolerances (%.3g mm, %.3g deg) of the link errors these poses do "
                           "not identify",
                     s.model_length_mm, s.model_angle_deg);
  if (anyCounted(s.model_sag_deg))
    counted += (counted.empty() ? "" : " and ") +
               format("the gravity sag of joints 2 and 3 (%.3g and %.3g deg%s)", s.model_sag_deg[0],
                      s.model_sag_deg[1],
                      anyCounted(s.model_sag_mean_deg)
                          ? format(", means %.3g and %.3g deg: both have gravity's sign",
                                   s.model_sag_mean_deg[0], s.model_sag_mean_deg[1])
                                .c_str()
                          : "");
  // A calibration that identified the links leaves them for later ones at one placement.
  const std::string written =
      r.result.model_file.empty()
          ? std::string()
          : " This calibration identified the robot's links: its calibrated model (" +
                r.result.model_file +
                " beside this report, with the covariance of the link errors) is what later "
                "calibrations of this robot at one PSD placement are planned and solved with.";
  if (counted.empty()) return written.empty() ? std::string() : written.substr(1);
  return "The achieved sigmas count " + counted + " beside the noise." + written;
}

int jointOf(const ParameterRow& p) { return isOffset(p) ? p.name[5] - '0' : 0; }

std::string unitOf(const std::string& name) {
  if (name.size() > 4 && name.compare(name.size() - 4, 4, "_deg") == 0) return "deg";
  if (name.size() > 3 && name.compare(name.size() - 3, 3, "_mm") == 0) return "mm";
  return "";
}

std::vector<const PoseRow*> worstPoses(const SessionReport& r, std::size_t count) {
  std::vector<const PoseRow*> solved;
  for (const PoseRow& p : r.poses)
    if (p.solved) solved.push_back(&p);
  std::stable_sort(solved.begin(), solved.end(), [](const PoseRow* a, const PoseRow* b) {
    return a->normalised > b->normalised;
  });
  std::size_t keep = std::min(count, solved.size());
  while (keep < solved.size() && solved[keep]->outlier) ++keep;  // never hide an outlier
  solved.resize(keep);
  return solved;
}

std::vector<std::string> identity(const SessionReport& r) {
  const auto known = [](const std::string& s) { return s.empty() ? "not recorded" : s; };
  std::vector<std::string> lines;
  lines.push_back("Robot: " + known(r.cell().controller.robot_type) + ", serial " +
                  known(r.cell().controller.serial) + ", controller software (RobotWare) " +
                  known(r.cell().controller.software_version) +
                  (r.cell().controller.serial.empty() ? "" : ", as the controller reported them") +
                  ".");
  lines.push_back("PSD map: " + known(r.cell().psd_map) + ".");
  std::string when = "not recorded";
  if (r.result.finished_unix_s) {
    const std::time_t t = static_cast<std::time_t>(*r.result.finished_unix_s);
    std::tm local{};
    char text[64];
    if (::localtime_r(&t, &local) &&
        std::strftime(text, sizeof text, "%Y-%m-%d %H:%M %Z (UTC%z)", &local))
      when = text;
  }
  lines.push_back("Calibrated " + when + " by zerocal " + known(r.result.zerocal_version) + ".");
  return lines;
}

std::string remeasuredNote(const SessionReport& r) {
  if (r.remeasured().empty()) return "";
  std::string poses;
  for (std::size_t i = 0; i < r.remeasured().size(); ++i)
    poses += (i == 0                           ? ""
              : i + 1 == r.remeasured().size() ? " and "
                                               : ", ") +
             std::to_string(r.remeasured()[i]);
  return std::string(r.remeasured().size() == 1 ? "Pose " : "Poses ") + poses +
         " did not fit the others at first and " + (r.remeasured().size() == 1 ? "was" : "were") +
         " measured again; the result rests on the new measurement, and both are in the journal.";
}

bool refused(const SessionReport& r) { return r.usable() && !*r.usable(); }

std::string verdict(const SessionReport& r) {
  std::string v;
  if (r.usable()) {
    v = *r.usable() ? "VERDICT: usable. "
                    : "VERDICT: NOT USABLE, no correction is offered; do not change the robot. ";
    for (const std::string& reason : r.solve().verdict.reasons) v += "Why: " + reason + ". ";
  }
  v += r.solve().converged ? "The solve converged" : "THE SOLVE DID NOT CONVERGE: do not use";
  v += " (" + r.solve().message + ").";
  bool all = true;
  for (const ParameterRow& p : r.parameters)
    if (isOffset(p) && !p.identifiable) all = false;
  v += all ? " delta2..delta5 are all identified."
           : " Some of delta2..delta5 are NOT identifiable from these poses (see below).";
  if (r.solve().chi2_per_dof) {
    // Judged by the chi-square distribution with the result's degrees of freedom (its p-value),
    // not by a fixed ratio (docs/reading-a-result.md).
    const double c = *r.solve().chi2_per_dof;
    v += format(" Chi-square per degree of freedom %.2f (dof %d):", c, r.solve().dof);
    v += r.solve().chi2_p_value && *r.solve().chi2_p_value < 0.001
             ? format(
                   " the poses miss by more than the stated noise (p = %.2g); the "
                   "uncertainties are scaled up by sqrt(chi2/dof).",
                   *r.solve().chi2_p_value)
         : r.solve().chi2_p_value && *r.solve().chi2_p_value > 0.999
             ? " far below 1: the stated noise is too pessimistic."
             : " consistent with the stated noise.";
  }
  int outliers = 0;
  for (const PoseRow& p : r.poses) outliers += p.solved && p.outlier;
  if (outliers) v += format(" %d pose(s) did not fit the others and were left out.", outliers);
  return v;
}

namespace {

// One paragraph per offset: the correction the controller's reading needs, or why none is to be
// made. Said alike for every controller.
void correctionsOf(const SessionReport& r, std::vector<std::string>& p) {
  for (const ParameterRow& o : r.parameters) {
    if (!isOffset(o)) continue;
    const int j = jointOf(o);
    if (refused(r)) {
      p.push_back(format("Joint %d: the result is not usable; do not change it.", j));
      continue;
    }
    if (!o.identifiable) {
      p.push_back(format("Joint %d: not identifiable from these poses; do not change it (%s).", j,
                         o.reason.c_str()));
      continue;
    }
    const bool significant = !(o.ci95_low <= 0 && 0 <= o.ci95_high);
    p.push_back(format(
        "Joint %d: delta%d = %+.5f deg = %+.7f rad (sigma %.5f deg). Controller reading: add "
        "%+.5f deg. Zero moves by %+.5f deg = %+.7f rad arm side.%s",
        j, j, o.value, o.value * kDegToRad, o.sigma, o.value, -o.value, -o.value * kDegToRad,
        significant ? ""
                    : " Its 95% interval contains zero: the offset is not distinguishable from "
                      "zero and may be left alone."));
  }
}

}  // namespace

Section abbSection(const SessionReport& r) {
  Section s;
  s.heading = "ABB IRC5: the offsets as corrections (nothing is written to the controller)";
  auto& p = s.paragraphs;
  p.push_back(
      "What an offset means. zerocal's model is theta_i = q_i + theta_offset_i + delta_i, where "
      "q_i is the angle the controller reports for joint i (ABB's CJointT sign) and theta_i the "
      "joint's true angle in the nominal kinematic model (the DH table of the IRB 1600). All "
      "values are arm side: joint angles, not motor angles. A positive delta_i means the arm is "
      "turned delta_i further in the joint's positive direction than the controller believes: "
      "when the controller reports q_i the arm is at q_i + delta_i, and the arm is at its true "
      "zero when the controller reports -delta_i.");
  p.push_back(
      "The correction. For each joint below, the controller's reading must grow by delta_i at "
      "every arm position (new reading = old reading + delta_i); equivalently the joint's zero "
      "(its calibration position) moves by -delta_i on the arm side. Joints 1 and 6 cannot be "
      "determined by this method: leave them unchanged.");
  correctionsOf(r, p);
  p.push_back(
      "Where the IRC5 keeps joint calibration. MOC.cfg, type MOTOR_CALIB, one instance per motor "
      "(rob1_1 .. rob1_6), attribute cal_offset: the MOTOR-side resolver angle in radians (beside "
      "it valid_cal_offset and com_offset). Not ARM (joint bounds) and not ARM_CALIB (Absolute "
      "Accuracy). Read the present value from RAPID with ReadCfgData "
      "\"/MOC/MOTOR_CALIB/rob1_N\",\"cal_offset\",value, or over Robot Web Services at "
      "/rw/cfg/MOC/MOTOR_CALIB/instances/rob1_N. Write the present values down before changing "
      "anything.");
  p.push_back(
      "From arm side to motor side. An arm-side offset is not a cal_offset: the change of "
      "cal_offset for joint N is about the arm-side change in radians times the axis's gear "
      "ratio, wrapped to 2 pi, with a sign that depends on the axis (motor direction, and how "
      "the controller applies cal_offset): |change of cal_offset_N| = |ratio_N x delta_N in "
      "rad|. zerocal's reference does not hold the IRB 1600's gear ratios (they are not in the "
      "product specification). Look up for each axis, on the robot itself: the transmission "
      "ratio and its sign in the controller's MOC.cfg (type TRANSMISSION, instance rob1_N), and "
      "ABB's rule for the sign of a cal_offset change on that axis for the installed RobotWare. "
      "If the wrist axes are mechanically coupled on this arm (the controller's transmission "
      "data say so), a change on joint 4 or 5 also moves the arm-side zero of the axes after it: "
      "ask ABB before entering such a change.");
  p.push_back(
      "zerocal-lab apply computes these values: 'zerocal-lab apply SESSION_DIR --moc MOC.cfg --out "
      "NEW.cfg' reads the MOC.cfg of a controller backup, prints for each of joints 2..5 "
      "cal_offset_new = wrap(cal_offset_old - k x delta) with every sign, k the transmission of "
      "the robot file, and writes a copy of the file in which only those values changed "
      "(docs/apply.md).");
  p.push_back(
      "Checking the change. After an ABB-trained person has entered the new values and the "
      "controller has restarted, repeat the calibration with the same plan: every new delta "
      "should lie within about its 95% interval of zero. An offset that doubled instead of "
      "vanishing was entered with the wrong sign.");
  return s;
}

namespace {

Section otherControllerSection(const SessionReport& r, const std::string& kind) {
  Section s;
  s.heading = "Controller '" + kind + "': the offsets as corrections (nothing is written to it)";
  auto& p = s.paragraphs;
  p.push_back(
      "What an offset means. zerocal's model is theta_i = q_i + theta_offset_i + delta_i, where "
      "q_i is the angle the controller reports for joint i and theta_i the joint's true angle in "
      "the nominal kinematic model of the robot file. All values are arm side. A positive "
      "delta_i means the arm is turned delta_i further in the joint's positive direction than "
      "the controller believes.");
  p.push_back(
      "The correction. For each joint below, the controller's reading must grow by delta_i at "
      "every arm position; equivalently the joint's zero moves by -delta_i on the arm side. "
      "Enter it as the controller's own calibration procedure says. Joints 1 and 6 cannot be "
      "determined by this method: leave them unchanged.");
  correctionsOf(r, p);
  return s;
}

}  // namespace

Section controllerSection(const SessionReport& r) {
  const ResultFile& result = r.result;
  // A reference, a check and a verification write nothing: what they are instead.
  if (result.kind == SessionKind::kReference || result.kind == SessionKind::kCheck ||
      result.kind == SessionKind::kVerification) {
    Section s;
    s.heading = std::string("A ") + sessionKindName(result.kind) + ": nothing is written";
    if (result.kind == SessionKind::kReference)
      s.paragraphs.push_back(
          "This session recorded the robot's zeros as they are: its poses, the PSD centre and "
          "the laser line its solve found, and the controller's calibration values. Later checks "
          "and restores of this robot compare with it (zerocal start --kind check, --kind "
          "restore); against it the robot's link errors cancel. Its offsets above are absolute "
          "estimates, not offered for use.");
    if (result.check)
      s.paragraphs.push_back("Check against reference " + result.reference + ": " +
                             result.check->summary + ".");
    if (result.kind == SessionKind::kVerification)
      s.paragraphs.push_back(
          "This session measured what an apply left" +
          (result.reference.empty() ? std::string() : " against reference " + result.reference) +
          "; the apply's own session says whether it was kept.");
    for (const Drift& d : result.drift) s.paragraphs.push_back("Drift: " + d.summary + ".");
    return s;
  }
  // Sessions from before the kinds recorded none: they all ran on an IRC5.
  const nlohmann::json& config = r.session.config;
  std::string kind = "irc5";
  if (config.is_object() && config.contains("controller") && config["controller"].is_object() &&
      config["controller"].contains("kind") && config["controller"]["kind"].is_string())
    kind = config["controller"]["kind"].get<std::string>();
  Section s = kind == "irc5" ? abbSection(r) : otherControllerSection(r, kind);
  // Once written by `zerocal apply`, the values are not "nothing written": entered again by hand
  // they would be applied twice.
  if (r.applied && r.applied->outcome != "refused" && r.applied->outcome != "pass" &&
      r.applied->outcome != "fail")
    s.heading = (kind == "irc5" ? std::string("ABB IRC5") : "Controller '" + kind + "'") +
                ": the offsets as corrections (zerocal apply wrote them to the controller: see "
                "'Applied to the controller'; do not enter them again)";
  if (!result.reference.empty())
    s.paragraphs.insert(
        s.paragraphs.begin(),
        "A restore against reference " + result.reference +
            ": each offset below is the change of the joint's zero since the reference, and the "
            "correction brings the robot back to the zeros it had then (its programs' zeros). "
            "zerocal apply --confirm writes it online and verifies it by a check against the "
            "reference.");
  for (const Drift& d : result.drift) s.paragraphs.push_back("Drift: " + d.summary + ".");
  return s;
}

std::string wrap(const std::string& text, std::size_t width, std::size_t indent) {
  std::istringstream words(text);
  std::string word, line, out;
  const std::string pad(indent, ' ');
  while (words >> word) {
    if (!line.empty() && pad.size() + line.size() + 1 + word.size() > width) {
      out += pad + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty()) out += pad + line + "\n";
  return out;
}

Section applySection(const SessionReport& r) {
  Section s;
  if (!r.applied) return s;
  const apply::ApplyRecord& a = *r.applied;
  const bool verification_only = a.outcome == "pass" || a.outcome == "fail";
  const bool refused = a.outcome == "refused";
  s.heading = verification_only ? "Verification by measurement"
              : refused         ? "Not applied to the controller"
                                : "Applied to the controller";
  if (!a.transmissions.empty()) {
    std::string measured =
        "Transmissions measured on the cell before writing (motor angle per joint angle, a "
        "small joint move read with the controller's motor angles), robot file -> measured:";
    for (const apply::ApplyRecord::Transmission& t : a.transmissions)
      measured += format(" joint %d %+g -> %+.2f%s;", t.joint, t.configured, t.measured,
                         t.agrees ? "" : " (DISAGREES)");
    s.paragraphs.push_back(measured);
  }
  if (!verification_only && !refused) {
    std::string values = "MOC MOTOR_CALIB cal_offset, rad, before -> written:";
    for (int j = 2; j <= 5; ++j)
      values += format(" joint %d %.6f -> %.6f;", j, a.before_rad[j - 1], a.written_rad[j - 1]);
    s.paragraphs.push_back(values);
    for (const std::string& f : a.formulas) s.paragraphs.push_back(f);
  }
  static const std::map<std::string, std::string> kOutcome{
      {"verified", "Verified: the new values stay."},
      {"rolled_back", "ROLLED BACK: the verification did not pass; the backed-up values are back."},
      {"recovered",
       "RECOVERED: the apply was interrupted; the backed-up values were restored at the daemon's "
       "next start."},
      {"not_written",
       "RECOVERED: the apply was interrupted before any value it wrote took effect; nothing was "
       "restored."},
      {"interrupted",
       "INTERRUPTED: the apply did not finish; the daemon recovers it when it starts (it restores "
       "the backup only when the controller holds that apply's backup or written values)."},
      {"unrecovered",
       "UNRECOVERED: the apply was interrupted and the daemon could not recover it; nothing was "
       "written; sessions are refused until it is recovered or acknowledged."},
      {"acknowledged",
       "ACKNOWLEDGED: the apply was interrupted; the technician checked the controller's values "
       "by hand and acknowledged them."},
      {"error", "STOPPED with an error after the backup: see the message."},
      {"refused",
       "REFUSED: a transmission measured on the cell disagrees with the robot file; nothing was "
       "written."},
      {"pass", "Pass: every offset left is within its bound."},
      {"fail", "FAIL: an offset left is beyond its bound."}};
  const auto it = kOutcome.find(a.outcome);
  s.paragraphs.push_back((it != kOutcome.end() ? it->second : a.outcome) +
                         (a.message.empty() ? "" : " " + a.message));
  if (a.remaining) {
    std::string left = "Offsets left, as the verification" +
                       (a.verification.empty() ? "" : " (session " + a.verification + ")") +
                       " measured them:";
    for (int k = 0; k < 4; ++k)
      left += format(" delta%d %+.5f deg (sigma %.5f);", k + 2, (*a.remaining)[k].value_deg,
                     (*a.remaining)[k].sigma_deg);
    s.paragraphs.push_back(left);
  }
  if (a.later_check) {
    std::string later = "Verified again later (session " + a.later_check->session +
                        "): " + (a.later_check->outcome == "pass" ? "pass. " : "FAIL. ") +
                        a.later_check->message + ". Offsets left:";
    for (int k = 0; k < 4; ++k)
      later += format(" delta%d %+.5f deg (sigma %.5f);", k + 2,
                      a.later_check->remaining[k].value_deg, a.later_check->remaining[k].sigma_deg);
    s.paragraphs.push_back(later);
  }
  if (a.outcome == "verified") {
    s.paragraphs.push_back(
        "Taught positions (robtargets and jointtargets) move physically by the corrected offsets: "
        "check them at reduced speed.");
    s.paragraphs.push_back(
        "Absolute Accuracy data (MOC ARM_CALIB) and a later fine calibration at the "
        "synchronisation marks refer to the old zeros: they no longer match.");
  }
  return s;
}

}  // namespace zerocal::report::detail
