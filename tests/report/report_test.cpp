#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "session_fixture.h"
#include "zerocal/report/session_report.h"
#include "zerocal/store/journal.h"

namespace zerocal::report {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

int count(const std::string& haystack, const std::string& needle) {
  int n = 0;
  for (auto p = haystack.find(needle); p != std::string::npos; p = haystack.find(needle, p + 1))
    ++n;
  return n;
}

// Every non-void element closed in order: enough to know that a browser will not reparent the
// plots into some other element.
std::string unbalancedTag(const std::string& html) {
  static const std::regex tag(R"(<(/?)([a-zA-Z][a-zA-Z0-9]*)[^>]*?(/?)>)");
  static const std::vector<std::string> kVoid{"meta", "br", "hr", "img", "link", "input"};
  std::vector<std::string> open;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), tag); it != std::sregex_iterator();
       ++it) {
    const std::string name = (*it)[2];
    if ((*it)[3] == "/" || std::find(kVoid.begin(), kVoid.end(), name) != kVoid.end()) continue;
    if ((*it)[1] == "/") {
      if (open.empty() || open.back() != name)
        return "</" + name + "> closes " + (open.empty() ? "nothing" : "<" + open.back() + ">");
      open.pop_back();
    } else {
      open.push_back(name);
    }
  }
  return open.empty() ? "" : "<" + open.back() + "> never closed";
}

const SessionReport& plainSession() {
  static const SessionReport r = [] {
    test::FixtureOptions o;
    o.poses_without_path = {4};
    return parseSession(test::sessionFiles(o));
  }();
  return r;
}

const SessionReport& heldOutSession() {
  static const SessionReport r = [] {
    test::FixtureOptions o;
    o.poses = 12;
    o.held_out = {3, 8};
    return parseSession(test::sessionFiles(o));
  }();
  return r;
}

TEST(Parse, TakesOffsetsInTheSolverOrderWithPlanAndTruth) {
  const SessionReport& r = plainSession();
  EXPECT_EQ(r.session.id, "20261122T070000Z");
  EXPECT_TRUE(r.simulated());
  EXPECT_TRUE(r.solve().converged);
  ASSERT_EQ(r.parameters.size(), 8u);
  EXPECT_EQ(r.parameters[0].name, "delta2_deg");
  EXPECT_EQ(r.parameters[3].name, "delta5_deg");
  EXPECT_EQ(r.parameters[4].name, "laser_slope_1");
  for (int k = 0; k < 4; ++k) {
    EXPECT_TRUE(r.parameters[k].identifiable);
    ASSERT_TRUE(r.parameters[k].predicted_sigma);
    ASSERT_TRUE(r.parameters[k].truth);
    EXPECT_NEAR(r.parameters[k].value, *r.parameters[k].truth, 4 * r.parameters[k].sigma);
  }
  EXPECT_NEAR(*r.parameters[0].truth, -0.4, 1e-12);
  ASSERT_EQ(r.poses.size(), 10u);
  EXPECT_FALSE(r.poses[3].servo_path);
  ASSERT_TRUE(r.poses[0].servo_path);
  EXPECT_EQ(r.poses[0].servo_path->size(), 21u);
  EXPECT_GE(r.solve().not_identifiable.size(), 2u);
}

TEST(Parse, HeldOutPosesAreNotGivenSomeoneElsesResidual) {
  const SessionReport& r = heldOutSession();
  ASSERT_TRUE(r.result.validation);
  EXPECT_EQ(r.solve().pose_count, 10);
  ASSERT_EQ(r.poses.size(), 12u);
  EXPECT_FALSE(r.poses[2].solved);
  EXPECT_FALSE(r.poses[7].solved);
  EXPECT_TRUE(r.poses[3].solved);
  ASSERT_EQ(r.result.validation->poses.size(), 2u);
  EXPECT_EQ(r.result.validation->poses[0].pose, 3);
  EXPECT_GT(r.result.validation->rms_before_mm, 30 * r.result.validation->rms_after_mm);
}

TEST(Parse, ASkippedPoseIsListedWithItsReasonAndTheSolvedOnesKeepTheirResiduals) {
  test::FixtureOptions o;
  o.skipped = {2};
  const SessionReport r = parseSession(test::sessionFiles(o));
  EXPECT_EQ(r.solve().pose_count, 9);
  ASSERT_EQ(r.poses.size(), 10u);
  EXPECT_FALSE(r.poses[1].solved);
  EXPECT_EQ(r.poses[1].skipped, "spot not found");
  EXPECT_TRUE(r.poses[2].solved);
  EXPECT_TRUE(r.poses[2].skipped.empty());
  const std::string html = reportHtml(r);
  EXPECT_TRUE(contains(html, "skipped: spot not found")) << html.size();
  EXPECT_EQ(unbalancedTag(html), "");
}

// A pose measured again: both lines listed, the solve's residual on the later one, and a sentence
// that says so.
TEST(Parse, APoseMeasuredAgainIsSolvedFromItsLatestLineAndSaidSo) {
  test::FixtureOptions o;
  o.remeasured = {3};
  const SessionReport r = parseSession(test::sessionFiles(o));
  EXPECT_EQ(r.solve().pose_count, 10);
  ASSERT_EQ(r.poses.size(), 11u);
  EXPECT_EQ(r.poses[2].pose, 3);
  EXPECT_TRUE(r.poses[2].superseded);
  EXPECT_FALSE(r.poses[2].solved);
  EXPECT_EQ(r.poses[10].pose, 3);
  EXPECT_TRUE(r.poses[10].again);
  EXPECT_TRUE(r.poses[10].solved);
  EXPECT_FALSE(r.poses[10].superseded);
  EXPECT_EQ(r.remeasured(), std::vector<int>{3});
  const std::string summary = summaryText(r), html = reportHtml(r);
  for (const std::string& text : {summary, html})
    EXPECT_TRUE(contains(text, "Pose 3 did not fit the others at first and was measured again"))
        << text;
  EXPECT_TRUE(contains(html, "3 (again)"));
  EXPECT_TRUE(contains(html, ">measured again<"));
  EXPECT_EQ(unbalancedTag(html), "");
}

// The daemon's residuals name their journal lines (posesOf keeps each pose's line): each line is
// given the residual that names it, whatever the residuals' order.
TEST(Parse, ResidualsThatNameTheirJournalLinesAreJoinedByThem) {
  test::FixtureOptions o;
  o.skipped = {2};
  o.remeasured = {3};
  SessionFolder files = test::sessionFiles(o);
  for (std::size_t i = 0; i < files.journal.size(); ++i)
    files.journal[i].line = static_cast<int>(i) + 1;  // as readJournal has them
  // The solved lines in plan order: pose 1, (2 skipped), pose 3's second measurement, 4..10.
  std::vector<int> solved_lines{1, 11};
  for (int line = 4; line <= 10; ++line) solved_lines.push_back(line);
  std::vector<PoseResidual>& residuals = files.result.report.poses;
  ASSERT_EQ(residuals.size(), solved_lines.size());
  for (std::size_t k = 0; k < residuals.size(); ++k) residuals[k].source_line = solved_lines[k];
  std::swap(residuals[0], residuals[1]);  // not in plan order: only the lines say which is whose
  ASSERT_NE(residuals[0].miss_norm_mm, residuals[1].miss_norm_mm);

  const SessionReport r = parseSession(files);
  ASSERT_EQ(r.poses.size(), 11u);
  for (const PoseResidual& p : residuals) {
    const PoseRow& row = r.poses[p.source_line - 1];
    ASSERT_TRUE(row.solved) << "line " << p.source_line;
    EXPECT_EQ(row.miss_um, std::hypot(p.miss_mm.x(), p.miss_mm.y()) * 1000)
        << "line " << p.source_line;
  }
  EXPECT_FALSE(r.poses[1].solved);  // skipped
  EXPECT_FALSE(r.poses[2].solved);  // superseded by line 11
  EXPECT_TRUE(r.poses[2].superseded);

  // A residual of a line that is no pose solved (pose 3's first measurement): the files do not
  // belong together.
  residuals[1].source_line = 3;
  EXPECT_THROW(parseSession(files), ReportError);
}

TEST(Summary, GivesEachOffsetInDegreesAndRadiansWithSigmaAndInterval) {
  const SessionReport& r = plainSession();
  const std::string s = summaryText(r);
  for (int k = 0; k < 4; ++k) {
    const ParameterRow& p = r.parameters[k];
    char deg[64], rad[64], sigma[64], ci[96];
    std::snprintf(deg, sizeof deg, "%+.5f", p.value);
    std::snprintf(rad, sizeof rad, "%+.7f", p.value * M_PI / 180);
    std::snprintf(sigma, sizeof sigma, "%.5f", p.sigma);
    std::snprintf(ci, sizeof ci, "[%+.5f, %+.5f]", p.ci95_low, p.ci95_high);
    EXPECT_TRUE(contains(s, deg)) << deg << "\n" << s;
    EXPECT_TRUE(contains(s, rad)) << rad;
    EXPECT_TRUE(contains(s, sigma)) << sigma;
    EXPECT_TRUE(contains(s, ci)) << ci;
  }
  EXPECT_TRUE(contains(s, "ARM side"));
  std::string flowed = s;  // the fit line is wrapped at 100 columns
  std::replace(flowed.begin(), flowed.end(), '\n', ' ');
  char chi2[96];
  std::snprintf(chi2, sizeof chi2, "chi-square per degree of freedom %.2f, dof %d",
                *r.solve().chi2_per_dof, r.solve().dof);
  EXPECT_TRUE(contains(flowed, chi2)) << chi2;
  for (std::istringstream lines(s); std::getline(lines, flowed);)
    EXPECT_LE(flowed.size(), 100u) << flowed;
}

TEST(Summary, SaysWhatIsNotIdentifiableAndWhy) {
  const std::string s = summaryText(plainSession());
  EXPECT_TRUE(contains(s, "Not identifiable, and why:"));
  for (const auto& n : plainSession().solve().not_identifiable) {
    EXPECT_TRUE(contains(s, n.name + ":")) << n.name;
    EXPECT_TRUE(contains(s, n.reason.substr(0, 30))) << n.reason;
  }
}

// With several PSD placements: each placement's centre, the link errors under their own heading
// (not the laser line's), the unknowns counted with them, and what the achieved sigmas count.
TEST(Summary, SeveralPlacementsShowEachCentreAndTheLinkErrorsApart) {
  SessionReport r = plainSession();
  SolveReport& s = r.result.report;
  s.placements = {{1, 5, Eigen::Vector3d(900, 0, 400), Eigen::Vector3d(0.1, 0.1, 0.1)},
                  {2, 5, Eigen::Vector3d(600, 600, 500), Eigen::Vector3d(0.2, 0.2, 0.2)}};
  ParameterRow link;
  link.name = "da2_mm";
  link.value = -0.3;
  link.sigma = 0.1;
  link.identifiable = true;
  r.parameters.push_back(link);
  s.model_sag_deg = {0.007, 0.0042};
  const std::string text = summaryText(r);
  EXPECT_TRUE(contains(text, "PSD centre at placement 2 (5 poses): 600.000 600.000 500.000 mm"))
      << text;
  EXPECT_FALSE(contains(text, "PSD centre in the base frame"));
  const auto laser = text.find("Laser line on the flange");
  const auto links = text.find("Link errors of the arm");
  ASSERT_NE(links, std::string::npos);
  EXPECT_LT(laser, links);
  EXPECT_LT(links, text.find("  da2_mm"));
  EXPECT_TRUE(contains(text, "unknowns identified")) << text;
  EXPECT_FALSE(contains(text, "of 11,"));
  EXPECT_TRUE(contains(text, "gravity sag of joints 2 and 3 (0.007 and 0.0042 deg)"));
  s.model_sag_mean_deg = {0.0065, 0.004};    // drawn together: the text says why
  const std::string drawn = summaryText(r);  // wrapped at 100 columns
  EXPECT_TRUE(contains(drawn, "(0.007 and 0.0042 deg, means 0.0065")) << drawn;
  EXPECT_TRUE(contains(drawn, "deg: both have gravity's sign)")) << drawn;
  const std::string html = reportHtml(r);
  EXPECT_TRUE(contains(html, "PSD centre at placement 2 (5 poses)"));
  EXPECT_TRUE(contains(html, "unknowns identified"));
  // One placement reads as before.
  const std::string one = summaryText(plainSession());
  EXPECT_TRUE(contains(one, "PSD centre in the base frame"));
  EXPECT_TRUE(contains(one, "of 11,"));
  EXPECT_FALSE(contains(one, "Link errors of the arm"));
}

// The robot as its controller identified itself, the map, the version and the local time, in
// both renderings; a result from before they were recorded says so instead of inventing them.
TEST(Summary, NamesTheRobotThePsdMapTheVersionAndTheLocalTime) {
  const char* saved = std::getenv("TZ");
  const std::string old_tz = saved ? saved : "";
  ::setenv("TZ", "CET-1CEST", 1);
  ::tzset();
  const std::string summary = summaryText(plainSession());
  const std::string html = reportHtml(plainSession());
  saved ? ::setenv("TZ", old_tz.c_str(), 1) : ::unsetenv("TZ");
  ::tzset();
  for (const std::string& text : {summary, html}) {
    EXPECT_TRUE(contains(text, "IRB 1600-10/1.45, serial 1600-504321")) << text;
    EXPECT_TRUE(contains(text, "RobotWare) 6.15.01.00")) << text;
    EXPECT_TRUE(contains(text, "fingerprint 0123456789abcdef")) << text;
    EXPECT_TRUE(contains(text, "2026-12-01 16:00 CET (UTC+0100) by zerocal 0.1.0")) << text;
  }
  // The verdict comes first, then who and when.
  EXPECT_LT(summary.find("The solve converged"), summary.find("Robot: "));

  test::FixtureOptions older;
  older.identity = false;
  const std::string old = summaryText(parseSession(test::sessionFiles(older)));
  EXPECT_TRUE(contains(old, "Robot: not recorded, serial not recorded")) << old;
  EXPECT_TRUE(contains(old, "Calibrated not recorded by zerocal not recorded.")) << old;
}

TEST(Html, HasAPrintLayoutWithTheResultOnAPageOfItsOwn) {
  const std::string html = reportHtml(plainSession());
  EXPECT_TRUE(contains(html, "@media print"));
  EXPECT_TRUE(contains(html, "section.result { break-after: page; }"));
  EXPECT_LT(html.find("<section class=\"result\">"), html.find("Joint offsets"));
  EXPECT_LT(html.find("Joint offsets"), html.find("</section>"));
  EXPECT_LT(html.find("</section>"), html.find("Per-pose residuals"));
  // Every column of the worst poses has a heading and every row a word in it.
  EXPECT_FALSE(contains(html, "<th></th>"));
  EXPECT_FALSE(contains(html, "<td></td></tr>"));
}

TEST(Html, ResidualsOfManyPosesAreGroupedByPlacementWithLabelsThatDoNotRunTogether) {
  test::FixtureOptions o;
  o.poses = 40;
  SessionFolder files = test::sessionFiles(o);
  for (std::size_t i = 0; i < files.session.plan.poses.size(); ++i)
    files.session.plan.poses[i].placement = i < 14 ? 1 : i < 27 ? 2 : 3;
  const std::string h = reportHtml(parseSession(files));
  std::string residuals = h.substr(h.find("id=\"residuals\""));
  residuals = residuals.substr(0, residuals.find("</svg>"));
  EXPECT_EQ(count(residuals, "<rect "), 40 + 1) << "a bar per pose (+ legend)";
  for (const char* name : {">placement 1<", ">placement 2<", ">placement 3<"})
    EXPECT_EQ(count(residuals, name), 1) << name;
  // Pose labels: every second of 40 (at most 24), and the last.
  EXPECT_EQ(count(residuals, "text-anchor=\"middle\">1</text>"), 1);
  EXPECT_EQ(count(residuals, "text-anchor=\"middle\">2</text>"), 0);
  EXPECT_EQ(count(residuals, "text-anchor=\"middle\">40</text>"), 1);
  // With one placement no group is named.
  const std::string one = reportHtml(parseSession(test::sessionFiles(o)));
  EXPECT_FALSE(contains(one, ">placement 1<"));
}

// The robot's history as the daemon's record gives it: two calibrations (this session the
// second, delta4 withheld by the first), an apply of the first, and a check against a reference.
std::vector<record::HistoryEntry> robotHistory(const std::string& current) {
  std::vector<record::HistoryEntry> h(3);
  h[0].session.session = "20261101T070000Z";
  h[0].session.kind = "calibration";
  h[0].session.started_unix_s = 1'793'516'400;
  h[0].session.offsets = {record::RecordedOffset{0.31, 0.002}, record::RecordedOffset{-0.52, 0.003},
                          std::nullopt, record::RecordedOffset{0.05, 0.004}};
  record::ControllerEvent apply;
  apply.kind = record::ControllerEventKind::kApply;
  apply.outcome = "verified";
  apply.time_unix_s = 1'793'517'000;
  h[0].events = {apply};
  h[1].session = h[0].session;
  h[1].session.session = current;
  h[1].session.started_unix_s = 1'795'000'000;
  h[1].session.offsets[2] = record::RecordedOffset{0.12, 0.004};
  h[2].session.session = "20261123T070000Z";
  h[2].session.kind = "check";
  h[2].session.reference = "20261120T070000Z";
  h[2].session.started_unix_s = 1'795'100'000;
  h[2].session.offsets = {record::RecordedOffset{0.001, 0.002}, record::RecordedOffset{0, 0.002},
                          record::RecordedOffset{0, 0.002}, record::RecordedOffset{0, 0.002}};
  return h;
}

std::string svgOf(const std::string& html, const std::string& id) {
  const std::size_t at = html.find("id=\"" + id + "\"");
  if (at == std::string::npos) return "";
  const std::string rest = html.substr(at);
  return rest.substr(0, rest.find("</svg>"));
}

TEST(Html, ACalibrationShowsTheRobotsCalibrationsOverTimeFromItsRecord) {
  SessionReport r = plainSession();
  EXPECT_FALSE(contains(reportHtml(r), "zeros over time")) << "no record, no trend";
  r.history = robotHistory(r.session.id);
  const std::string h = reportHtml(r);
  EXPECT_TRUE(contains(
      h, escapeHtml("Each zero's offset as the robot's 2 calibrations in the record found it")));
  for (const char* id : {"trend-delta2", "trend-delta3", "trend-delta4", "trend-delta5"}) {
    const std::string svg = svgOf(h, id);
    ASSERT_FALSE(svg.empty()) << id;
    EXPECT_EQ(count(svg, "class=\"change\""), 1) << id << ": the first one's apply";
    EXPECT_EQ(count(svg, "class=\"point current\""), 1) << id;
  }
  EXPECT_EQ(count(svgOf(h, "trend-delta2"), "class=\"point"), 2) << "not the check";
  EXPECT_EQ(count(svgOf(h, "trend-delta2"), "class=\"bar\""), 2);
  EXPECT_EQ(count(svgOf(h, "trend-delta4"), "class=\"withheld\""), 1);
  EXPECT_EQ(count(svgOf(h, "trend-delta4"), "class=\"point"), 1);
  EXPECT_TRUE(contains(svgOf(h, "trend-delta2"),
                       "20261101T070000Z (calibration): +0.31000 +- 0.00200 deg"));
  EXPECT_EQ(unbalancedTag(h), "");
}

TEST(Html, ACheckShowsTheChangesSinceItsReferenceOnly) {
  SessionReport r = plainSession();
  r.session.kind = SessionKind::kCheck;
  r.result.reference = "20261120T070000Z";
  r.history = robotHistory("20261101T080000Z");
  r.history[2].session.session = r.session.id;  // this check
  const std::string h = reportHtml(r);
  EXPECT_TRUE(contains(h, escapeHtml("Each zero's change since reference 20261120T070000Z, as "
                                     "the 1 session compared with it in the record found it")));
  const std::string svg = svgOf(h, "trend-delta3");
  EXPECT_EQ(count(svg, "class=\"point current\""), 1);
  EXPECT_EQ(count(svg, "class=\"point"), 1) << "no calibration on the axis of the changes";
  // A reference's report has none: what it measured is no zero's change.
  r.session.kind = SessionKind::kReference;
  r.result.reference.clear();
  EXPECT_FALSE(contains(reportHtml(r), "zeros over time"));
}

TEST(Summary, ListsTheWorstPosesFirst) {
  const SessionReport& r = plainSession();
  const std::string s = summaryText(r);
  int worst = 0;
  double worst_value = -1;
  for (const PoseRow& p : r.poses)
    if (p.normalised > worst_value) worst_value = p.normalised, worst = p.pose;
  char row[64];
  std::snprintf(row, sizeof row, "  %5d %10.1f %11.2f", worst, r.poses[worst - 1].miss_um,
                worst_value);
  const auto table = s.find("Worst poses");
  ASSERT_NE(table, std::string::npos);
  // The first row under the header is the worst pose.
  const auto first_row = s.find('\n', s.find('\n', table) + 1) + 1;
  EXPECT_EQ(s.substr(first_row, std::strlen(row)), row) << s.substr(table, 300);
}

TEST(Summary, AbbSectionStatesTheSignAndWhatToLookUp) {
  const SessionReport& r = plainSession();
  const std::string s = summaryText(r);
  EXPECT_TRUE(contains(s, "nothing is written to the controller"));
  EXPECT_TRUE(contains(s, "theta_i = q_i + theta_offset_i + delta_i"));
  EXPECT_TRUE(contains(s, "new reading = old reading + delta_i"));
  EXPECT_TRUE(contains(s, "MOTOR_CALIB"));
  EXPECT_TRUE(contains(s, "cal_offset"));
  EXPECT_TRUE(contains(s, "TRANSMISSION"));
  EXPECT_TRUE(contains(s, "Joints 1 and 6"));
  // The correction of joint 2 is the negated offset, in both units.
  const ParameterRow& d2 = r.parameters[0];
  char zero[128];
  std::snprintf(zero, sizeof zero, "Zero moves by %+.5f deg = %+.7f rad", -d2.value,
                -d2.value * M_PI / 180);
  EXPECT_TRUE(contains(s, zero)) << zero;
}

// Another controller kind gets the corrections, never the IRC5's MOC data or its apply command.
TEST(Summary, AnotherControllerKindGetsTheCorrectionsWithoutTheIrc5s) {
  SessionReport r = plainSession();
  r.session.config["controller"]["kind"] = "line";
  const std::string s = summaryText(r);
  EXPECT_TRUE(contains(s, "Controller 'line': the offsets as corrections"));
  EXPECT_TRUE(contains(s, "theta_i = q_i + theta_offset_i + delta_i"));
  EXPECT_FALSE(contains(s, "MOTOR_CALIB"));
  EXPECT_FALSE(contains(s, "zerocal apply"));
  EXPECT_FALSE(contains(reportHtml(r), "cal_offset"));
  const ParameterRow& d2 = r.parameters[0];
  char zero[128];
  std::snprintf(zero, sizeof zero, "Zero moves by %+.5f deg = %+.7f rad", -d2.value,
                -d2.value * M_PI / 180);
  EXPECT_TRUE(contains(s, zero)) << zero;
  r.session.config["controller"]["kind"] = "irc5";
  EXPECT_TRUE(contains(summaryText(r), "MOTOR_CALIB"));
}

TEST(Summary, ValidationWhenPosesWereHeldOutAndSaysSoWhenNot) {
  EXPECT_TRUE(contains(summaryText(plainSession()), "no poses were held out"));
  const SessionReport& r = heldOutSession();
  const std::string s = summaryText(r);
  char rms[128];
  std::snprintf(rms, sizeof rms, "RMS: before (nominal model) %.4f mm, after calibration %.4f mm",
                r.result.validation->rms_before_mm, r.result.validation->rms_after_mm);
  EXPECT_TRUE(contains(s, rms)) << s;
}

TEST(Summary, AnUnidentifiableOffsetHasNoNumberAndNoCorrection) {
  SessionFolder files = test::sessionFiles();
  ParameterEstimate& d2 = files.result.report.parameters[0];
  ASSERT_EQ(d2.name, "delta2_deg");
  d2.identifiable = false;
  d2.value = d2.sigma = d2.ci95_low = d2.ci95_high = std::nan("");
  d2.reason = "joint 1 spans 0.0 deg over the poses";
  files.result.report.not_identifiable.push_back(
      {"delta2_deg", "joint 1 spans 0.0 deg over the poses"});
  files.result.report.converged = false;
  const SessionReport r = parseSession(files);
  const std::string s = summaryText(r);
  EXPECT_TRUE(contains(s, "THE SOLVE DID NOT CONVERGE")) << s;
  EXPECT_TRUE(contains(s, "delta2  NOT IDENTIFIABLE")) << s;
  EXPECT_TRUE(contains(s, "Joint 2: not identifiable from these poses; do not change it")) << s;
  EXPECT_FALSE(contains(s, "Joint 2: delta2 ="));
  const std::string h = reportHtml(r);
  EXPECT_EQ(unbalancedTag(h), "");
  EXPECT_TRUE(contains(h, "verdict fail"));
}

TEST(Html, IsSelfContainedAndBalanced) {
  const std::string h = reportHtml(heldOutSession());
  EXPECT_EQ(h.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(unbalancedTag(h), "");
  EXPECT_FALSE(contains(h, "<script"));
  EXPECT_FALSE(contains(h, "src="));
  EXPECT_FALSE(contains(h, "<link"));
  // The only URL is the SVG namespace, which is a name, not a resource.
  EXPECT_EQ(count(h, "http"), count(h, "xmlns=\"http://www.w3.org/2000/svg\""));
}

TEST(Html, HasEveryPlotWithAxisLabels) {
  const std::string h = reportHtml(heldOutSession());
  for (const char* id : {"residuals", "servo-paths", "sigma-offsets", "sigma-laser", "validation"})
    EXPECT_TRUE(contains(h, std::string("<svg class=\"plot\" id=\"") + id + "\"")) << id;
  EXPECT_TRUE(contains(h, "miss / what is allowed"));
  EXPECT_TRUE(contains(h, "sigma (millidegrees)"));
  EXPECT_TRUE(contains(h, "spot distance on the PSD (mm, log)"));
  // Bars: 10 solved poses; 4 predicted + 4 achieved offsets; 2 x 2 held-out poses.
  const auto residuals = h.substr(h.find("id=\"residuals\""));
  EXPECT_EQ(count(residuals.substr(0, residuals.find("</svg>")), "<rect "), 10 + 1);  // + legend
  const auto offsets = h.substr(h.find("id=\"sigma-offsets\""));
  EXPECT_EQ(count(offsets.substr(0, offsets.find("</svg>")), "<rect "), 8 + 2);  // + legend
  EXPECT_EQ(count(h, "<polyline class=\"path\""), 12);
}

TEST(Html, ServoPathSaysNotRecordedWhenAbsent) {
  const std::string h = reportHtml(plainSession());
  EXPECT_EQ(count(h, "<polyline class=\"path\""), 9);
  EXPECT_EQ(count(h, ">not recorded</text>"), 1);
  EXPECT_TRUE(contains(h, "No poses were held out"));
}

TEST(Html, ServoPanelsAreScaledToTheirPath) {
  // The fixture's paths start 2 mm from the reading: a +-2 or +-2.5 mm panel, every point in it.
  const std::string h = reportHtml(plainSession());
  EXPECT_EQ(count(h, ">+-2.5 mm, 21 points, 1.00 s</text>") +
                count(h, ">+-2 mm, 21 points, 1.00 s</text>"),
            9);
  const std::regex point(R"(([-0-9.]+),([-0-9.]+) )");
  const auto start = h.find("<polyline class=\"path\" points=\"");
  const std::string first = h.substr(start, h.find("\"/>", start) - start);
  int points = 0;
  for (auto it = std::sregex_iterator(first.begin(), first.end(), point);
       it != std::sregex_iterator(); ++it, ++points) {
    const double x = std::stod((*it)[1]), y = std::stod((*it)[2]);
    EXPECT_TRUE(x >= 12 && x <= 12 + 160 && y >= 26 && y <= 26 + 160) << x << "," << y;
  }
  EXPECT_EQ(points, 21);
}

TEST(Html, NoServoPathAtAllIsOneSentenceNotAnEmptyPlot) {
  test::FixtureOptions o;
  o.poses = 8;
  o.poses_without_path = {1, 2, 3, 4, 5, 6, 7, 8};
  const std::string h = reportHtml(parseSession(test::sessionFiles(o)));
  EXPECT_FALSE(contains(h, "id=\"servo-paths\""));
  EXPECT_TRUE(contains(h, "The spot path was not recorded for any pose"));
}

TEST(Html, EscapesEveryTextFromTheFiles) {
  test::FixtureOptions o;
  o.id = "x<script>alert('1')</script>&";
  o.plan_description = "plan \"A\" <b>bold</b> & more";
  const SessionReport r = parseSession(test::sessionFiles(o));
  const std::string h = reportHtml(r);
  EXPECT_FALSE(contains(h, "<script>"));
  EXPECT_FALSE(contains(h, "<b>bold"));
  EXPECT_TRUE(contains(h, "x&lt;script&gt;alert(&#39;1&#39;)&lt;/script&gt;&amp;"));
  EXPECT_TRUE(contains(h, "plan &quot;A&quot; &lt;b&gt;bold&lt;/b&gt; &amp; more"));
  EXPECT_EQ(unbalancedTag(h), "");
  EXPECT_EQ(escapeHtml("a<b>&\"'"), "a&lt;b&gt;&amp;&quot;&#39;");
}

TEST(Files, WritesSummaryAndReportBesideTheResult) {
  const std::string dir = test::makeSession("write");
  writeSessionReport(dir);
  const std::string summary = readFile(fs::path(dir) / "summary.txt");
  const std::string html = readFile(fs::path(dir) / "report.html");
  EXPECT_EQ(summary, summaryText(parseSession(readSessionFiles(dir))));
  EXPECT_TRUE(contains(html, "</html>"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "report.html.tmp"));
  writeSessionReport(dir);  // again: the files are rewritten, not appended to
  EXPECT_EQ(readFile(fs::path(dir) / "summary.txt"), summary);
}

TEST(Files, MissingResultSaysTheSessionIsUnfinished) {
  const std::string dir = test::makeSession("no-result");
  fs::remove(fs::path(dir) / "result.json");
  try {
    writeSessionReport(dir);
    FAIL() << "expected ReportError";
  } catch (const ReportError& e) {
    EXPECT_TRUE(contains(e.what(), "result.json")) << e.what();
    EXPECT_TRUE(contains(e.what(), "unfinished")) << e.what();
  }
  EXPECT_FALSE(fs::exists(fs::path(dir) / "summary.txt"));
}

TEST(Files, MissingFolderOrSessionFile) {
  EXPECT_THROW(writeSessionReport("/nonexistent/zerocal/session"), ReportError);
  const std::string dir = test::makeSession("no-session");
  fs::remove(fs::path(dir) / "session.json");
  try {
    writeSessionReport(dir);
    FAIL() << "expected ReportError";
  } catch (const ReportError& e) {
    EXPECT_TRUE(contains(e.what(), "session.json")) << e.what();
  }
}

TEST(Files, BadJournalLineIsAnError) {
  const std::string dir = test::makeSession("bad-journal");
  std::string journal = readFile(fs::path(dir) / "journal.jsonl");
  journal.replace(journal.find('\n') + 1, 1, "#");  // corrupt the second line, not the last
  std::ofstream(fs::path(dir) / "journal.jsonl") << journal;
  EXPECT_THROW(writeSessionReport(dir), JournalError);
}

TEST(Files, JournalWithAPoseMissingIsInconsistent) {
  const std::string dir = test::makeSession("short-journal");
  std::string journal = readFile(fs::path(dir) / "journal.jsonl");
  journal.erase(journal.rfind('\n', journal.size() - 2) + 1);  // drop the last pose
  std::ofstream(fs::path(dir) / "journal.jsonl") << journal;
  try {
    writeSessionReport(dir);
    FAIL() << "expected ReportError";
  } catch (const ReportError& e) {
    EXPECT_TRUE(contains(e.what(), "result.json solved 10 poses, but journal.jsonl has 9"))
        << e.what();
  }
}

TEST(Files, ResultOfAnotherSessionOrWithoutAKey) {
  SessionFolder files = test::sessionFiles();
  files.result.session = "20200101T000000Z";
  EXPECT_THROW(parseSession(files), ReportError);
  // What is on disk is read by the store's codecs, which name the file and the member.
  const std::string dir = test::makeSession("without-a-key");
  nlohmann::json result = nlohmann::json::parse(readFile(fs::path(dir) / "result.json"));
  result.erase("converged");
  std::ofstream(fs::path(dir) / "result.json") << result.dump();
  try {
    readSessionFiles(dir);
    FAIL() << "expected ReportError";
  } catch (const ReportError& e) {
    EXPECT_EQ(std::string(e.what()), "result.json: 'converged' is missing");
  }
  result["converged"] = true;
  result["written_by_a_newer_version"] = 1;  // unknown keys are tolerated
  std::ofstream(fs::path(dir) / "result.json") << result.dump();
  EXPECT_NO_THROW(parseSession(readSessionFiles(dir)));
  std::string journal = readFile(fs::path(dir) / "journal.jsonl");
  const std::size_t path = journal.find("\"servo_path\":[[");
  ASSERT_NE(path, std::string::npos);
  journal.insert(path + 14, "[0.0,1.0],");  // a sample of two numbers, not the last line
  std::ofstream(fs::path(dir) / "journal.jsonl") << journal;
  EXPECT_THROW(readSessionFiles(dir), JournalError);
}

TEST(Files, InvalidJsonNamesTheFile) {
  const std::string dir = test::makeSession("bad-json");
  std::ofstream(fs::path(dir) / "result.json") << "{\"converged\": tru";
  try {
    writeSessionReport(dir);
    FAIL() << "expected ReportError";
  } catch (const ReportError& e) {
    EXPECT_TRUE(contains(e.what(), "result.json")) << e.what();
    EXPECT_TRUE(contains(e.what(), "not valid JSON")) << e.what();
  }
}

}  // namespace
}  // namespace zerocal::report
