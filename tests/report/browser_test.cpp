// The report opens in a real browser and its plots render: Debian's Chromium, headless, takes a
// screenshot of report.html and of copies in which one plot's drawing, or only its data marks, is
// removed (the <svg> element kept with its size, so the layout does not move). Each plot and its
// data must change many pixels; a copy with nothing removed must change none. Chromium missing is a
// failure, not a skip: scripts/install-deps.sh installs it, and CI always runs that (configure with
// -DZEROCAL_BROWSER_TESTS=OFF where it cannot be installed).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>

#include "png.h"
#include "session_fixture.h"
#include "zerocal/report/session_report.h"

namespace zerocal::report {
namespace {

namespace fs = std::filesystem;

std::string findChromium() {
  if (const char* env = std::getenv("ZEROCAL_CHROMIUM"); env && *env) return env;
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':'))
    for (const char* name : {"chromium", "chromium-browser"})
      if (fs::exists(fs::path(dir) / name)) return (fs::path(dir) / name).string();
  return {};
}

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The page with the drawing of plot `id` removed: the <svg> element stays, with its size.
std::string withoutPlot(const std::string& html, const std::string& id) {
  const auto start = html.find("<svg class=\"plot\" id=\"" + id + "\"");
  if (start == std::string::npos) return {};
  const auto open_end = html.find('>', start) + 1;
  const auto close = html.find("</svg>", open_end);
  return html.substr(0, open_end) + html.substr(close);
}

// The page with only the data marks of plot `id` removed (bars, which carry a <title>, the spot
// paths and their end points), axes and labels kept: what is left to see if the data drew.
std::string withoutMarks(const std::string& html, const std::string& id) {
  const auto start = html.find("<svg class=\"plot\" id=\"" + id + "\"");
  if (start == std::string::npos) return {};
  const auto close = html.find("</svg>", start);
  static const std::regex marks(
      R"(<rect [^>]*><title>[^<]*</title></rect>|<polyline class="path"[^>]*/>|<circle [^>]*/>)");
  const std::string svg = html.substr(start, close - start);
  const std::string stripped = std::regex_replace(svg, marks, "");
  if (stripped == svg) return {};
  return html.substr(0, start) + stripped + html.substr(close);
}

class Browser : public ::testing::Test {
 protected:
  void SetUp() override {
    chromium_ = findChromium();
    ASSERT_FALSE(chromium_.empty())
        << "chromium is not installed: scripts/install-deps.sh installs it (Debian package "
           "'chromium'); without it configure with -DZEROCAL_BROWSER_TESTS=OFF";
    test::FixtureOptions o;
    o.poses = 12;
    o.held_out = {3, 8};
    o.poses_without_path = {5};
    dir_ = test::makeSession("browser", o);
    writeSessionReport(dir_);
  }

  // Screenshot of `html` written beside the report (so that it sees the same folder).
  test::Image render(const std::string& name, const std::string& html) {
    const fs::path page = fs::path(dir_) / (name + ".html");
    std::ofstream(page) << html;
    const fs::path png = fs::path(dir_) / (name + ".png");
    const fs::path profile = fs::path(dir_) / ("profile-" + name);
    fs::remove(png);
    fs::remove_all(profile);
    // A fresh profile and no network features: nothing but the file is loaded.
    const std::string cmd = "timeout 120 '" + chromium_ +
                            "' --headless --no-sandbox --disable-gpu --disable-quic "
                            "--no-first-run --disable-background-networking "
                            "--disable-component-update --disable-sync --hide-scrollbars "
                            "--user-data-dir='" +
                            profile.string() + "' --screenshot='" + png.string() +
                            "' --window-size=1200,5000 'file://" + page.string() + "' > '" +
                            (fs::path(dir_) / (name + ".log")).string() + "' 2>&1";
    const int rc = std::system(cmd.c_str());
    fs::remove_all(profile);  // tens of MB each; the screenshot and its log are kept
    EXPECT_EQ(rc, 0) << cmd << "\n" << readFile(fs::path(dir_) / (name + ".log"));
    if (!fs::exists(png)) {
      ADD_FAILURE() << "no screenshot from: " << cmd;
      return {};
    }
    return test::readPng(png.string());
  }

  static long changedPixels(const test::Image& a, const test::Image& b) {
    if (a.width != b.width || a.height != b.height || a.rgb.empty()) return -1;
    long n = 0;
    for (int y = 0; y < a.height; ++y)
      for (int x = 0; x < a.width; ++x) {
        const auto* p = a.pixel(x, y);
        const auto* q = b.pixel(x, y);
        if (std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) + std::abs(p[2] - q[2]) > 24) ++n;
      }
    return n;
  }

  std::string chromium_, dir_;
};

TEST_F(Browser, EveryPlotOfTheReportRenders) {
  const std::string html = readFile(fs::path(dir_) / "report.html");
  const test::Image full = render("full", html);
  ASSERT_EQ(full.width, 1200);
  // Control: the same page again changes nothing, so a difference below is the plot's drawing.
  EXPECT_LT(changedPixels(full, render("again", html)), 50);
  for (const char* id :
       {"residuals", "servo-paths", "sigma-offsets", "sigma-laser", "validation"}) {
    const std::string stripped = withoutPlot(html, id);
    ASSERT_FALSE(stripped.empty()) << "the report has no plot '" << id << "'";
    const long changed = changedPixels(full, render(std::string("without-") + id, stripped));
    std::cout << "plot '" << id << "': " << changed << " pixels drawn\n";
    // A plot is axes, ticks, labels and its marks: thousands of pixels at 1200 px wide.
    EXPECT_GT(changed, 2000) << "plot '" << id << "' draws (almost) nothing in Chromium";
    // And its data, not only its frame: bars and paths with coordinates a browser accepts.
    const std::string unmarked = withoutMarks(html, id);
    ASSERT_FALSE(unmarked.empty()) << "plot '" << id << "' has no data marks";
    const long marks = changedPixels(full, render(std::string("unmarked-") + id, unmarked));
    std::cout << "plot '" << id << "': " << marks << " pixels of data marks\n";
    EXPECT_GT(marks, 500) << "the data of plot '" << id << "' does not draw in Chromium";
  }
}

}  // namespace
}  // namespace zerocal::report
