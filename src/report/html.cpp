// report.html: one file that opens anywhere (a laptop on the shop floor without network), so the
// CSS and the plots are inline and there is no script; every text from the files is escaped.
#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>
#include <optional>
#include <sstream>

#include "content.h"

namespace zerocal::report {
namespace {

using detail::format;
using detail::num;

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

std::string esc(const std::string& s) { return escapeHtml(s); }

// Tick values for an axis from lo to hi: 1, 2 or 5 times a power of ten apart, about n of them.
std::vector<double> linearTicks(double lo, double hi, int n = 5) {
  const double raw = (hi - lo) / n;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  double step = power;
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (m * power >= raw) {
      step = m * power;
      break;
    }
  std::vector<double> ticks;
  for (double t = std::ceil(lo / step) * step; t <= hi + step * 1e-9; t += step)
    ticks.push_back(std::abs(t) < step * 1e-9 ? 0.0 : t);
  return ticks;
}

// A round number not below x (x > 0) and not far above it: a panel's half-width.
double niceCeil(double x) {
  const double power = std::pow(10.0, std::floor(std::log10(x)));
  for (const double m : {1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0})
    if (m * power >= x) return m * power;
  return 10 * power;
}

std::string tickLabel(double v) {
  const double a = std::abs(v);
  if (a == 0) return "0";
  if (a >= 1e4 || a < 1e-3) return format("%.0e", v);
  return format("%g", v);
}

struct Series {
  std::string name, colour;
  std::vector<double> values;  // one per category; NaN: no bar
};

// An SVG plot's opening: its size, its title for a screen reader and as text at its top left.
std::string plotHead(const std::string& id, const std::string& title, double w, double h,
                     double left) {
  return format(
             "<svg class=\"plot\" id=\"%s\" xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" "
             "height=\"%.0f\" viewBox=\"0 0 %.0f %.0f\" role=\"img\">\n",
             id.c_str(), w, h, w, h) +
         "<title>" + esc(title) + "</title>\n" +
         format("<text x=\"%.0f\" y=\"20\" class=\"ptitle\">", left) + esc(title) + "</text>\n";
}

// A bar chart with grouped series, axis labels, ticks and an optional horizontal reference line.
// Log scale for quantities spanning decades (aiming errors before and after calibration).
// `groups`, when given, names each category's group (a PSD placement): a line separates the
// groups and each name stands under its span. Beyond 24 categories every k-th is labelled, so
// that the labels do not run together (each bar's tooltip names it).
std::string barChart(const std::string& id, const std::string& title,
                     const std::vector<std::string>& categories, const std::vector<Series>& series,
                     const std::string& x_label, const std::string& y_label, bool log_scale,
                     double reference = std::nan(""), const std::string& reference_label = "",
                     const std::vector<std::string>& groups = {}) {
  const double w = 640, h = 316, left = 72, right = 16, top = 50, bottom = 56;
  const double pw = w - left - right, ph = h - top - bottom;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Series& s : series)
    for (const double v : s.values)
      if (std::isfinite(v) && (!log_scale || v > 0)) lo = std::min(lo, v), hi = std::max(hi, v);
  if (std::isfinite(reference)) lo = std::min(lo, reference), hi = std::max(hi, reference);
  if (!std::isfinite(lo)) lo = log_scale ? 0.1 : 0, hi = 1;
  std::vector<double> ticks;
  if (log_scale) {
    lo = std::pow(10.0, std::floor(std::log10(lo)));
    hi = std::pow(10.0, std::ceil(std::log10(hi)));
    if (hi <= lo) hi = lo * 10;
    for (double t = lo; t <= hi * 1.0001; t *= 10) ticks.push_back(t);
  } else {
    lo = std::min(lo, 0.0);
    hi = std::max(hi * 1.1, 0.0);
    if (hi <= lo) hi = lo + 1;
    ticks = linearTicks(lo, hi);
    hi = std::max(hi, ticks.back());
    lo = std::min(lo, ticks.front());
  }
  auto y = [&](double v) {
    const double f = log_scale
                         ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo))
                         : (v - lo) / (hi - lo);
    return top + ph * (1 - f);
  };
  std::ostringstream o;
  o << plotHead(id, title, w, h, left);
  for (const double t : ticks) {
    o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"grid\"/>", left,
                left + pw, y(t), y(t));
    o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"end\">%s</text>\n",
                left - 6, y(t) + 4, tickLabel(t).c_str());
  }
  const double group = pw / std::max<std::size_t>(categories.size(), 1);
  const double bar = group * 0.8 / std::max<std::size_t>(series.size(), 1);
  const double base = log_scale ? lo : 0.0;
  const std::size_t label_every = (categories.size() + 23) / 24;
  for (std::size_t c = 0; c < categories.size(); ++c) {
    const double gx = left + group * c + group * 0.1;
    for (std::size_t s = 0; s < series.size(); ++s) {
      const double v = c < series[s].values.size() ? series[s].values[c] : std::nan("");
      if (!std::isfinite(v) || (log_scale && v <= 0)) continue;
      const double y0 = y(base), y1 = y(v);
      o << format("<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"%s\">",
                  gx + bar * s, std::min(y0, y1), bar, std::max(std::abs(y0 - y1), 0.5),
                  series[s].colour.c_str())
        << "<title>" << esc(categories[c] + ", " + series[s].name + ": " + format("%.4g", v))
        << "</title></rect>\n";
    }
    if (c % label_every == 0 || c + 1 == categories.size())
      o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"middle\">",
                  left + group * (c + 0.5), top + ph + 16)
        << esc(categories[c]) << "</text>\n";
  }
  if (groups.size() == categories.size()) {
    for (std::size_t first = 0; first < groups.size();) {
      std::size_t end = first;
      while (end < groups.size() && groups[end] == groups[first]) ++end;
      if (first > 0)
        o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"axis\"/>",
                    left + group * first, left + group * first, top, top + ph + 34);
      o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"middle\">",
                  left + group * (first + end) / 2.0, top + ph + 32)
        << esc(groups[first]) << "</text>\n";
      first = end;
    }
  }
  if (std::isfinite(reference))
    o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"ref\"/>", left,
                left + pw, y(reference), y(reference))
      << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"end\">", left + pw,
                y(reference) - 4)
      << esc(reference_label) << "</text>\n";
  o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"axis\"/>", left,
              left + pw, y(base), y(base));
  o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"axis\"/>\n", left,
              left, top, top + ph);
  o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"label\" text-anchor=\"middle\">", left + pw / 2,
              h - 10)
    << esc(x_label) << "</text>\n";
  o << format(
           "<text transform=\"translate(16 %.1f) rotate(-90)\" class=\"label\" "
           "text-anchor=\"middle\">",
           top + ph / 2)
    << esc(y_label) << "</text>\n";
  // Legend, top right.
  double lx = left + pw;
  for (auto s = series.rbegin(); s != series.rend(); ++s) {
    lx -= 12 + 7.0 * s->name.size() + 14;
    o << format("<rect x=\"%.1f\" y=\"28\" width=\"10\" height=\"10\" fill=\"%s\"/>", lx,
                s->colour.c_str())
      << format("<text x=\"%.1f\" y=\"37\" class=\"tick\">", lx + 14) << esc(s->name)
      << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

// Small multiples, one per pose: the spot on the PSD (u right, v up, mm) from the start of the
// servo (green) to the recorded reading (red). Each panel has its own scale, printed in it,
// because a spot search spans millimetres and a fine servo micrometres.
std::string servoPaths(const std::vector<PoseRow>& poses) {
  const int columns = 6;
  const double cell = 160, gap = 12, title_h = 26, label_h = 18;
  const int rows = static_cast<int>((poses.size() + columns - 1) / columns);
  const double w = columns * (cell + gap) + gap;
  const double h = title_h + rows * (cell + label_h + gap) + gap;
  std::ostringstream o;
  o << format(
      "<svg class=\"plot\" id=\"servo-paths\" xmlns=\"http://www.w3.org/2000/svg\" "
      "width=\"%.0f\" height=\"%.0f\" viewBox=\"0 0 %.0f %.0f\" role=\"img\">\n",
      w, h, w, h);
  o << "<title>PSD spot path during each servo</title>\n";
  o << format(
      "<text x=\"%.0f\" y=\"18\" class=\"ptitle\">PSD spot path during each servo "
      "(u right, v up, mm; green start, red recorded)</text>\n",
      gap);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const PoseRow& p = poses[i];
    const double x0 = gap + (i % columns) * (cell + gap);
    const double y0 = title_h + (i / columns) * (cell + label_h + gap);
    const double cx = x0 + cell / 2, cy = y0 + cell / 2;
    o << format("<rect x=\"%.1f\" y=\"%.1f\" width=\"%.0f\" height=\"%.0f\" class=\"panel\"/>", x0,
                y0, cell, cell);
    o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\">pose %d</text>\n", x0 + 4, y0 + 13,
                p.pose);
    if (!p.servo_path || p.servo_path->empty()) {
      o << format(
          "<text x=\"%.1f\" y=\"%.1f\" class=\"label\" text-anchor=\"middle\">not "
          "recorded</text>\n",
          cx, cy);
      continue;
    }
    double extent = 0;
    for (const SpotPathPoint& s : *p.servo_path)
      if (s.spot.finite())
        extent = std::max({extent, std::abs(s.spot.u_mm), std::abs(s.spot.v_mm)});
    extent = extent > 0 ? niceCeil(extent * 1.05) : 1e-3;
    const double scale = (cell / 2 - 10) / extent;
    o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"grid\"/>", x0,
                x0 + cell, cy, cy)
      << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"grid\"/>\n", cx, cx,
                y0, y0 + cell);
    o << "<polyline class=\"path\" points=\"";
    for (const SpotPathPoint& s : *p.servo_path)
      if (s.spot.finite())
        o << format("%.2f,%.2f ", cx + s.spot.u_mm * scale, cy - s.spot.v_mm * scale);
    o << "\"/>\n";
    const PsdSpot& first = p.servo_path->front().spot;
    const PsdSpot& last = p.servo_path->back().spot;
    o << format("<circle cx=\"%.2f\" cy=\"%.2f\" r=\"4\" class=\"start\"/>",
                cx + first.u_mm * scale, cy - first.v_mm * scale)
      << format("<circle cx=\"%.2f\" cy=\"%.2f\" r=\"4\" class=\"end\"/>\n", cx + last.u_mm * scale,
                cy - last.v_mm * scale);
    o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\">+-%s mm, %zu points, %.2f s</text>\n",
                x0, y0 + cell + 13, tickLabel(extent).c_str(), p.servo_path->size(),
                p.servo_path->back().t_s - p.servo_path->front().t_s);
  }
  o << "</svg>\n";
  return o.str();
}

std::string td(const std::string& s, const char* cls = nullptr) {
  return cls ? std::string("<td class=\"") + cls + "\">" + esc(s) + "</td>"
             : "<td>" + esc(s) + "</td>";
}

// One point of a trend: a session's value of one offset (deg), absent when it withheld it.
struct TrendPoint {
  double t = 0;  // its start, unix s
  std::optional<record::RecordedOffset> offset;
  bool current = false;  // the session of this report
  std::string label;     // for its tooltip
};

// A point per session over time with its +-3 sigma bar (the band a check is judged by), a
// withheld value as a hollow mark on the time axis, this session's point in red, and the
// controller's applies and rollbacks (`changes`, unix s) as vertical dashed lines.
std::string trendPlot(const std::string& id, const std::string& title,
                      const std::vector<TrendPoint>& points, const std::vector<double>& changes) {
  const double w = 520, h = 220, left = 72, right = 16, top = 40, bottom = 40;
  const double pw = w - left - right, ph = h - top - bottom;
  double t0 = std::numeric_limits<double>::infinity(), t1 = -t0;
  double lo = t0, hi = -t0;
  for (const TrendPoint& p : points) {
    t0 = std::min(t0, p.t), t1 = std::max(t1, p.t);
    if (p.offset)
      lo = std::min(lo, p.offset->value_deg - 3 * p.offset->sigma_deg),
      hi = std::max(hi, p.offset->value_deg + 3 * p.offset->sigma_deg);
  }
  for (const double t : changes) t0 = std::min(t0, t), t1 = std::max(t1, t);
  if (!(t1 - t0 >= 60)) t0 -= 30, t1 += 30;  // one session, or a few within a minute
  if (!std::isfinite(lo)) lo = -0.01, hi = 0.01;
  const double pad = std::max((hi - lo) * 0.08, 0.001);
  lo -= pad, hi += pad;
  const std::vector<double> ticks = linearTicks(lo, hi, 4);
  lo = std::min(lo, ticks.front()), hi = std::max(hi, ticks.back());
  const auto x = [&](double t) { return left + pw * (t - t0) / (t1 - t0); };
  const auto y = [&](double v) { return top + ph * (hi - v) / (hi - lo); };
  std::ostringstream o;
  o << plotHead(id, title, w, h, left);
  for (const double t : ticks)
    o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"grid\"/>", left,
                left + pw, y(t), y(t))
      << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"end\">%s</text>\n",
                left - 6, y(t) + 4, tickLabel(t).c_str());
  for (const double t : changes)
    o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"change\"/>\n", x(t),
                x(t), top, top + ph);
  for (const TrendPoint& p : points) {
    const char* cls = p.current ? "point current" : "point";
    if (!p.offset) {
      o << format("<circle cx=\"%.1f\" cy=\"%.1f\" r=\"4\" class=\"withheld\">", x(p.t), top + ph)
        << "<title>" << esc(p.label + ": withheld") << "</title></circle>\n";
      continue;
    }
    const double v = p.offset->value_deg, bar = 3 * p.offset->sigma_deg;
    o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"bar\"/>", x(p.t),
                x(p.t), y(v - bar), y(v + bar))
      << format("<circle cx=\"%.1f\" cy=\"%.1f\" r=\"4\" class=\"%s\">", x(p.t), y(v), cls)
      << "<title>" << esc(p.label + format(": %+.5f +- %.5f deg", v, p.offset->sigma_deg))
      << "</title></circle>\n";
  }
  o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"axis\"/>", left,
              left + pw, top + ph, top + ph)
    << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"axis\"/>\n", left,
              left, top, top + ph);
  const auto date = [](double t) {
    const std::time_t s = static_cast<std::time_t>(t);
    std::tm utc{};
    ::gmtime_r(&s, &utc);
    char text[32];
    std::strftime(text, sizeof text, "%Y-%m-%d %H:%M", &utc);
    return std::string(text);
  };
  o << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"start\">", left,
              top + ph + 16)
    << esc(date(t0)) << "</text>\n"
    << format("<text x=\"%.1f\" y=\"%.1f\" class=\"tick\" text-anchor=\"end\">", left + pw,
              top + ph + 16)
    << esc(date(t1) + " UTC") << "</text>\n";
  o << format(
      "<text x=\"16\" y=\"%.1f\" class=\"label\" text-anchor=\"middle\" "
      "transform=\"rotate(-90 16 %.1f)\">deg</text>\n",
      top + ph / 2, top + ph / 2);
  o << "</svg>\n";
  return o.str();
}

// The robot's zeros over time, from its record: the sessions that measured what this one did.
// Compared with a reference: those compared with the same one, each zero's change since it.
// A calibration: the robot's calibrations, each zero's offset. Empty for other sessions, and
// when the report has no record.
std::string trendSection(const SessionReport& r) {
  const std::string& reference = r.result.reference;
  const bool calibration = r.session.kind == SessionKind::kCalibration && reference.empty();
  if (r.history.empty() || (reference.empty() && !calibration)) return "";
  std::vector<const record::HistoryEntry*> chosen;
  std::vector<double> changes;
  for (const record::HistoryEntry& h : r.history) {
    const record::SessionEntry& s = h.session;
    if (reference.empty() ? (s.kind == "calibration" && s.reference.empty())
                          : s.reference == reference)
      chosen.push_back(&h);
    for (const record::ControllerEvent& e : h.events)
      if ((e.kind == record::ControllerEventKind::kApply && e.outcome != "refused" &&
           e.outcome != "not_written") ||
          (e.kind == record::ControllerEventKind::kRollback && e.outcome == "restored"))
        changes.push_back(e.time_unix_s);
  }
  if (chosen.empty()) return "";
  std::ostringstream o;
  o << "<h2>This robot's zeros over time</h2>\n<p>"
    << esc(reference.empty()
               ? format("Each zero's offset as the robot's %d calibration%s in the record found "
                        "it",
                        static_cast<int>(chosen.size()), chosen.size() == 1 ? "" : "s")
               : format("Each zero's change since reference %s, as the %d session%s compared "
                        "with it in the record found it",
                        reference.c_str(), static_cast<int>(chosen.size()),
                        chosen.size() == 1 ? "" : "s"))
    << esc(": bars are +-3 sigma (the band a check judges by), this session in red, a hollow "
           "mark where a value was withheld, dashed lines where an apply or a rollback changed "
           "the controller's values.")
    << "</p>\n";
  for (int k = 0; k < kOffsetCount; ++k) {
    std::vector<TrendPoint> points;
    for (const record::HistoryEntry* h : chosen) {
      TrendPoint p;
      p.t = static_cast<double>(h->session.started_unix_s);
      p.offset = h->session.offsets[static_cast<std::size_t>(k)];
      p.current = h->session.session == r.session.id;
      p.label = h->session.session + " (" + h->session.kind + ")";
      points.push_back(p);
    }
    const std::string name = unknownName(k).substr(0, 6);
    o << trendPlot("trend-" + name, name + (reference.empty() ? "" : ", change since reference"),
                   points, changes);
  }
  return o.str();
}

constexpr const char* kStyle = R"(
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; }
td, th { border: 1px solid #ccc; padding: 2px 8px; }
td.n { text-align: right; font-family: monospace; }
.bad { color: #b00; font-weight: bold; }
.verdict { padding: 0.5em; background: #f4f4f4; border-left: 4px solid #4a7; }
.verdict.fail { border-left-color: #b00; }
svg.plot { display: block; margin: 0.8em 0; background: #fff; }
svg .ptitle { font: bold 13px sans-serif; }
svg .label { font: 12px sans-serif; fill: #333; }
svg .tick { font: 11px sans-serif; fill: #444; }
svg .grid { stroke: #e2e2e2; stroke-width: 1; }
svg .axis { stroke: #333; stroke-width: 1; }
svg .ref { stroke: #b00; stroke-width: 1.5; stroke-dasharray: 6 4; }
svg .panel { fill: #fafafa; stroke: #999; }
svg .path { fill: none; stroke: #2a5db0; stroke-width: 1.5; }
svg .start { fill: #2a2; } svg .end { fill: #c22; }
svg .point { fill: #2a5db0; } svg .point.current { fill: #c22; }
svg .withheld { fill: #fff; stroke: #666; } svg .bar { stroke: #555; stroke-width: 1.5; }
svg .change { stroke: #888; stroke-dasharray: 4 3; }
.identity { color: #444; }
@media print {
  body { margin: 0; max-width: none; font-size: 10pt; }
  .verdict { border: 1px solid #999; }
  h2 { break-after: avoid; }
  table, svg.plot, li { break-inside: avoid; }
  section.result { break-after: page; }
}
)";

}  // namespace

std::string reportHtml(const SessionReport& r) {
  std::ostringstream o;
  o << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>"
    << esc("zerocal report " + r.session.id) << "</title>\n<style>" << kStyle
    << "</style>\n</head>\n<body>\n";
  // The result (verdict, identity, offsets) is one section, printed on a page of its own.
  o << "<section class=\"result\">\n";
  o << "<h1>" << esc("Calibration report, session " + r.session.id) << "</h1>\n";
  if (r.simulated()) o << "<p class=\"bad\">Simulated cell: the truth is known and shown.</p>\n";
  if (!r.session.plan.description.empty())
    o << "<p>Plan: " << esc(r.session.plan.description) << "</p>\n";
  o << "<p class=\"verdict" << (r.solve().converged && !detail::refused(r) ? "" : " fail") << "\">"
    << esc(detail::verdict(r)) << "</p>\n";
  if (!r.remeasured().empty()) o << "<p>" << esc(detail::remeasuredNote(r)) << "</p>\n";
  o << "<p class=\"identity\">";
  const std::vector<std::string> identity = detail::identity(r);
  for (std::size_t i = 0; i < identity.size(); ++i) o << (i ? "<br>" : "") << esc(identity[i]);
  o << "</p>\n";
  if (!r.solve().suspect_poses.empty()) {
    o << "<p>Suspect poses (the result does not rest on them):</p>\n<ul>\n";
    for (const SuspectPose& sp : r.solve().suspect_poses)
      o << "<li>" << esc(format("pose %d (line %d): ", sp.pose, sp.source_line) + sp.reason)
        << "</li>\n";
    o << "</ul>\n";
  }
  o << "<p>"
    << esc(format("Solved from %d poses (%s model, %s cost); noise %s mm (%s); ",
                  r.solve().pose_count, modelName(r.solve()).c_str(),
                  costName(r.solve().cost).c_str(), num("%.4f", r.solve().noise_mm).c_str(),
                  noiseSourceName(r.solve()).c_str()));
  if (r.solve().chi2_per_dof)
    o << esc(format("chi-square per degree of freedom %.2f (dof %d); ", *r.solve().chi2_per_dof,
                    r.solve().dof));
  o << esc(format("RMS miss %.1f um; %s, condition number %s.", r.solve().rms_miss_mm * 1000,
                  detail::rankText(r).c_str(), num("%.1f", r.solve().condition_number).c_str()))
    << "</p>\n";

  // Offsets.
  o << "<h2>Joint offsets (arm side: joint angle, not motor angle)</h2>\n"
       "<p>The true joint angle is the controller's angle plus delta. The 95% interval contains "
       "the true offset 19 times in 20.</p>\n<table>\n<tr><th>offset</th><th>value (deg)</th>"
       "<th>value (rad)</th><th>sigma (deg)</th><th>sigma (rad)</th><th>95% interval (deg)</th>";
  if (r.simulated()) o << "<th>truth (deg)</th>";
  o << "</tr>\n";
  for (const ParameterRow& p : r.parameters) {
    if (!detail::isOffset(p)) continue;
    o << "<tr>" << td(p.name.substr(0, 6));
    if (!p.identifiable || detail::refused(r)) {
      o << "<td colspan=\"5\" class=\"bad\">"
        << (p.identifiable ? "withheld: the result is not usable" : "not identifiable (see below)")
        << "</td>" << (r.simulated() ? td(p.truth ? format("%+.5f", *p.truth) : "", "n") : "")
        << "</tr>\n";
      continue;
    }
    o << td(format("%+.5f", p.value), "n") << td(format("%+.7f", p.value * kDegToRad), "n")
      << td(format("%.5f", p.sigma), "n") << td(format("%.7f", p.sigma * kDegToRad), "n")
      << td(format("[%+.5f, %+.5f]", p.ci95_low, p.ci95_high), "n");
    if (r.simulated()) o << td(p.truth ? format("%+.5f", *p.truth) : "", "n");
    o << "</tr>\n";
  }
  o << "</table>\n<h2>Not identifiable, and why</h2>\n<ul>\n";
  for (const auto& n : r.solve().not_identifiable)
    o << "<li><b>" << esc(n.name) << "</b>: " << esc(n.reason) << "</li>\n";
  o << "</ul>\n</section>\n";

  // Residuals.
  o << "<h2>Per-pose residuals</h2>\n";
  std::vector<std::string> cats, placements;
  Series norm{"miss / sigma", "#2a5db0", {}};
  for (const PoseRow& p : r.poses) {
    cats.push_back(std::to_string(p.pose));
    placements.push_back(p.placement > 0 ? "placement " + std::to_string(p.placement) : "");
    norm.values.push_back(p.solved ? p.normalised : std::nan(""));
  }
  const bool several =
      std::any_of(r.poses.begin(), r.poses.end(), [](const PoseRow& p) { return p.placement > 1; });
  o << "<p>Each bar is the pose's miss in what the given noise";
  if (detail::linksWeighMisses(r)) o << " and the robot's link tolerances";
  o << " allow at it: about 1 for a pose that fits, beyond 3.5 one that stands out (not scaled "
       "by how well the whole fit went).</p>\n";
  o << barChart("residuals", "How far each pose's laser line misses the PSD point", cats, {norm},
                "pose (held-out and skipped poses have no bar)", "miss / what is allowed (1)",
                false, 3.5, "outlier threshold 3.5",
                several ? placements : std::vector<std::string>{});
  o << "<p>Worst poses:</p>\n<table>\n<tr><th>pose</th><th>miss (um)</th><th>miss / sigma</th>"
       "<th>stand-off (mm)</th><th>fit</th></tr>\n";
  for (const PoseRow* p : detail::worstPoses(r))
    o << "<tr>" << td(std::to_string(p->pose), "n") << td(format("%.1f", p->miss_um), "n")
      << td(format("%.2f", p->normalised), "n") << td(format("%.1f", p->standoff_mm), "n")
      << (p->outlier ? "<td class=\"bad\">suspect: beyond 3.5 sigma</td>" : "<td>consistent</td>")
      << "</tr>\n";
  o << "</table>\n";

  // Servo paths.
  o << "<h2>PSD spot path during each servo</h2>\n";
  const bool any_path = std::any_of(r.poses.begin(), r.poses.end(),
                                    [](const PoseRow& p) { return p.servo_path.has_value(); });
  if (any_path)
    o << servoPaths(r.poses);
  else
    o << "<p>The spot path was not recorded for any pose (the journal has no servo_path).</p>\n";

  // Predicted versus achieved.
  o << "<h2>Predicted versus achieved uncertainty</h2>\n"
       "<p>Predicted: the plan's Cramer-Rao bound before any move (session.json). Achieved: the "
       "one-sigma uncertainty of this solve (result.json).</p>\n";
  if (const std::string note = detail::toleranceNote(r); !note.empty())
    o << "<p>" << esc(note) << "</p>\n";
  std::vector<std::string> offset_cats, laser_cats;
  Series pred_o{"predicted", "#999999", {}}, ach_o{"achieved", "#2a5db0", {}};
  Series pred_l{"predicted", "#999999", {}}, ach_l{"achieved", "#2a5db0", {}};
  for (const ParameterRow& p : r.parameters) {
    const double pred = p.predicted_sigma ? *p.predicted_sigma : std::nan("");
    const double ach = p.identifiable ? p.sigma : std::nan("");
    if (detail::isOffset(p)) {
      offset_cats.push_back(p.name.substr(0, 6));
      pred_o.values.push_back(pred * 1000);
      ach_o.values.push_back(ach * 1000);
    } else if (detail::isLaser(p)) {
      // "laser_offset_1_mm" -> "offset 1 (mm)": the axis is narrow, the table has the full name.
      // (Link errors, with several PSD placements, are in the table only.)
      const std::string unit = detail::unitOf(p.name);
      std::string label = p.name.substr(p.name.rfind("laser_", 0) == 0 ? 6 : 0);
      if (!unit.empty())
        label = label.substr(0, label.size() - unit.size() - 1) + " (" + unit + ")";
      std::replace(label.begin(), label.end(), '_', ' ');
      laser_cats.push_back(label);
      pred_l.values.push_back(pred);
      ach_l.values.push_back(ach);
    }
  }
  o << barChart("sigma-offsets", "Joint offsets: one-sigma uncertainty", offset_cats,
                {pred_o, ach_o}, "parameter", "sigma (millidegrees)", false);
  o << barChart("sigma-laser", "Laser line: one-sigma uncertainty (log scale)", laser_cats,
                {pred_l, ach_l}, "parameter (slopes dimensionless, offsets in mm)",
                "sigma (parameter unit)", true);
  o << "<table>\n<tr><th>parameter</th><th>predicted sigma</th><th>achieved sigma</th>"
       "<th>achieved / predicted</th></tr>\n";
  for (const ParameterRow& p : r.parameters) {
    const std::string unit = detail::unitOf(p.name);
    o << "<tr>" << td(p.name)
      << td(p.predicted_sigma ? num("%.3g", *p.predicted_sigma) + " " + unit : "n/a", "n")
      << td(p.identifiable ? num("%.3g", p.sigma) + " " + unit : "not identifiable", "n")
      << td(p.predicted_sigma && p.identifiable && *p.predicted_sigma > 0
                ? format("%.2f", p.sigma / *p.predicted_sigma)
                : "",
            "n")
      << "</tr>\n";
  }
  o << "</table>\n";

  // Validation.
  o << "<h2>Validation on held-out poses</h2>\n";
  if (!r.result.validation) {
    o << "<p>No poses were held out of this solve (<code>zerocal-lab solve --holdout K</code> does "
         "it).</p>\n";
  } else {
    std::vector<std::string> vc;
    Series before{"before (nominal)", "#c77c2a", {}}, after{"after calibration", "#2a5db0", {}};
    for (const HeldOutPose& h : r.result.validation->poses) {
      vc.push_back("pose " + std::to_string(h.pose));
      before.values.push_back(h.before.on_psd_norm_mm);
      after.values.push_back(h.after.on_psd_norm_mm);
    }
    o << barChart("validation", "Aiming error at the PSD on poses the solve did not see", vc,
                  {before, after}, "held-out pose", "spot distance on the PSD (mm, log)", true);
    o << "<table>\n<tr><th>pose</th><th>before (mm)</th><th>after (mm)</th><th>after u, v (mm)"
         "</th><th>after, line miss (mm)</th></tr>\n";
    for (const HeldOutPose& h : r.result.validation->poses)
      o << "<tr>" << td(std::to_string(h.pose), "n")
        << td(format("%.4f", h.before.on_psd_norm_mm), "n")
        << td(format("%.4f", h.after.on_psd_norm_mm), "n")
        << td(format("%+.4f, %+.4f", h.after.on_psd_mm[0], h.after.on_psd_mm[1]), "n")
        << td(format("%.4f", h.after.miss_mm), "n") << "</tr>\n";
    o << "</table>\n<p>"
      << esc(format("RMS before (nominal model) %.4f mm, after calibration %.4f mm.",
                    r.result.validation->rms_before_mm, r.result.validation->rms_after_mm))
      << "</p>\n";
  }

  // What to enter into the controller.
  const detail::Section abb = detail::controllerSection(r);
  o << "<h2>" << esc(abb.heading) << "</h2>\n";
  for (const std::string& p : abb.paragraphs) o << "<p>" << esc(p) << "</p>\n";
  const detail::Section applied = detail::applySection(r);
  if (!applied.heading.empty()) {
    o << "<h2>" << esc(applied.heading) << "</h2>\n";
    for (const std::string& p : applied.paragraphs) o << "<p>" << esc(p) << "</p>\n";
  }

  o << trendSection(r);

  // Every pose.
  o << "<h2>Recorded poses</h2>\n<table>\n<tr><th>pose</th><th>q1..q6 (deg)</th><th>u, v (mm)"
       "</th><th>miss (um)</th><th>stand-off (mm)</th></tr>\n";
  for (const PoseRow& p : r.poses) {
    if (!p.skipped.empty()) {
      o << "<tr>" << td(std::to_string(p.pose), "n") << td("skipped: " + p.skipped) << td("")
        << td("") << td("") << "</tr>\n";
      continue;
    }
    std::string q;
    for (const double v : p.joints_deg) q += format("%.4f ", v);
    const std::string pose = std::to_string(p.pose) + (p.again ? " (again)" : "");
    o << "<tr>" << td(pose, "n") << td(q, "n")
      << td(format("%+.4f, %+.4f", p.spot.u_mm, p.spot.v_mm), "n")
      << td(p.solved       ? format("%.1f", p.miss_um)
            : p.superseded ? "measured again"
                           : "held out",
            "n")
      << td(p.solved ? format("%.1f", p.standoff_mm) : "", "n") << "</tr>\n";
  }
  o << "</table>\n";
  o << "<p>";
  const std::vector<std::string> centres = detail::placementCentres(r);
  if (centres.empty())
    o << esc(format("PSD centre in the base frame: %.3f %.3f %.3f mm.",
                    r.solve().estimate.target_mm[0], r.solve().estimate.target_mm[1],
                    r.solve().estimate.target_mm[2]));
  for (const std::string& c : centres) o << esc(c) << ". ";
  if (r.result.cell_time_s) o << esc(format(" Cell time %.1f s.", *r.result.cell_time_s));
  o << " Written by zerocal from " << esc(r.dir) << ".</p>\n</body>\n</html>\n";
  return o.str();
}

}  // namespace zerocal::report
