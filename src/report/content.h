// What the summary and the HTML report both say, decided once: formatting of numbers, the worst
// poses, the ABB section's statements. The two renderings differ only in markup.
#pragma once

#include <fmt/printf.h>

#include <string>
#include <vector>

#include "zerocal/calib/format.h"
#include "zerocal/report/session_report.h"

namespace zerocal::report::detail {

// printf's format, as long as the text is (fmt's sprintf: each argument formatted by its type).
template <typename... Args>
std::string format(const char* spec, const Args&... args) {
  return fmt::sprintf(spec, args...);
}

// "n/a" for a non-finite number, else printf with `fmt`.
std::string num(const char* fmt, double v);

bool isOffset(const ParameterRow& p);         // delta2_deg .. delta5_deg
bool isLaser(const ParameterRow& p);          // laser_slope_1 .. laser_offset_2_mm
int jointOf(const ParameterRow& p);           // 2 for delta2_deg
std::string unitOf(const std::string& name);  // "deg", "mm" or "" (dimensionless)

// Solved poses by decreasing normalised residual, at most `count`, plus any outlier beyond.
std::vector<const PoseRow*> worstPoses(const SessionReport& r, std::size_t count = 3);

// True when the result carries a verdict that refuses it: then no offset is shown as a correction.
bool refused(const SessionReport& r);

// One paragraph: the verdict and its reasons first, then did it converge, and is the noise
// believable.
std::string verdict(const SessionReport& r);

// A heading and paragraphs: the ABB section as plain sentences (no markup).
struct Section {
  std::string heading;
  std::vector<std::string> paragraphs;
};
Section abbSection(const SessionReport& r);
// The section for the session's controller (session.json's config.controller.kind): the ABB
// section for an IRC5 (and for sessions that recorded no kind: they all ran on one), the
// corrections without any controller's data for another kind.
Section controllerSection(const SessionReport& r);

// Whose calibration, with what and when, one sentence each: the robot as its controller
// identified itself, the PSD map, the zerocal version, the local date and time it finished.
// "not recorded" for what an older result lacks.
std::vector<std::string> identity(const SessionReport& r);

// One sentence on the poses measured again after the first solve named them; empty when none.
std::string remeasuredNote(const SessionReport& r);

// The latest online apply or verification (before / written / verdict / warnings), as plain
// sentences; an empty heading when there was none.
Section applySection(const SessionReport& r);

// "rank 11 of 11" for one PSD placement; with several, how many unknowns the poses identified of
// how many (offsets, laser line, each placement's centre, the link errors).
std::string rankText(const SessionReport& r);
// With several PSD placements, one sentence per placement's identified centre; empty with one.
std::vector<std::string> placementCentres(const SessionReport& r);
// What the achieved sigmas count beside the noise (the link or sag tolerances); empty when none.
// (zerocald's plans predict with the same tolerances.)
std::string toleranceNote(const SessionReport& r);

// True when each pose's normalised miss counts the link tolerances beside the noise (one PSD
// placement, the noise given, the tolerances or a calibrated model counted: the solver's link
// weighting).
bool linksWeighMisses(const SessionReport& r);

// Wraps text at `width` columns with `indent` spaces before every line.
std::string wrap(const std::string& text, std::size_t width, std::size_t indent);

}  // namespace zerocal::report::detail
