// The PSD configuration section (every problem at once), the map in YAML, and the map fitted from
// a sweep recorded through the simulated rig (board, FakeTransport, Usb1408fs) recovering
// positions in its valid zone to 2 um.
#include "zerocal/psd/psd_config.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "zerocal/error.h"
#include "zerocal/sim/psd_rig.h"

namespace zerocal::psd {
namespace {

using usb1408fs::InputMode;
using usb1408fs::Range;

std::vector<std::string> problemsOf(const std::string& yaml) {
  try {
    parsePsdConfig(YAML::Load(yaml), "test.yaml", ".");
  } catch (const ConfigError& e) {
    return e.problems();
  }
  return {};
}

bool mentions(const std::vector<std::string>& problems, const std::string& text) {
  return std::any_of(problems.begin(), problems.end(),
                     [&](const std::string& p) { return p.find(text) != std::string::npos; });
}

// One sweep for the whole file: the fit is the slow part and every map test can share it.
class FittedMap : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SimulatedPsdRig rig(7);
    sweep_ = new std::vector<SweepPoint>(sim::simulateSweep(rig, sim::SweepOptions{}));
    report_ = new MapFitReport;
    map_ = new PsdMap(PsdMap::fit(*sweep_, MapFitOptions{}, report_));
  }
  static void TearDownTestSuite() {
    delete map_;
    delete report_;
    delete sweep_;
  }
  static std::vector<SweepPoint>* sweep_;
  static MapFitReport* report_;
  static PsdMap* map_;
};
std::vector<SweepPoint>* FittedMap::sweep_ = nullptr;
MapFitReport* FittedMap::report_ = nullptr;
PsdMap* FittedMap::map_ = nullptr;

TEST(PsdConfig, DefaultsAreValid) {
  const PsdConfig config;
  EXPECT_TRUE(config.problems().empty());
  EXPECT_NO_THROW(config.validate("defaults"));
}

TEST(PsdConfig, ShippedExampleLoadsWithItsMap) {
  const PsdConfig config = loadPsdConfig(ZEROCAL_SOURCE_DIR "/config/psd.yaml");
  EXPECT_EQ(config.channels.x.number, 0);
  EXPECT_EQ(config.channels.sum.number, 2);
  EXPECT_EQ(config.channels.sum.range, Range::kBip5V);
  EXPECT_EQ(config.samples, 64u);
  ASSERT_TRUE(config.map.has_value());
  EXPECT_EQ(config.map->degree(), 7);
}

TEST(PsdConfig, ReadsEveryKey) {
  const PsdConfig config = parsePsdConfig(YAML::Load(R"(
serial: "01A2B3C4"
channels:
  x: {mode: single_ended, input: 5}
  y: {mode: single_ended, input: 6}
  sum: {mode: differential, input: 0, range_v: 2.5}
samples: 128
rate_hz: 8000
sum_threshold_v: 1.0
)"),
                                          "test.yaml", ".");
  EXPECT_EQ(config.serial, "01A2B3C4");
  EXPECT_EQ(config.channels.x.mode, InputMode::kSingleEnded);
  EXPECT_EQ(config.channels.y.number, 6);
  EXPECT_EQ(config.channels.sum.range, Range::kBip2_5V);
  EXPECT_EQ(config.samples, 128u);
  EXPECT_DOUBLE_EQ(config.rate_hz, 8000);
  EXPECT_DOUBLE_EQ(config.sum_off_threshold_v, 0.8);  // hysteresis follows the threshold
  EXPECT_FALSE(config.map.has_value());
}

TEST(PsdConfig, ReportsEveryProblemAtOnce) {
  const auto problems = problemsOf(R"(
channels:
  x: {mode: differential, input: 5, range_v: 5}
  y: {mode: diff, input: 1, range_v: 3}
  sum: {mode: single_ended, input: 2, range_v: 5}
samples: 1
rate_hz: 20000
sum_threshold_v: 0
smaples: 64
)");
  EXPECT_TRUE(mentions(problems, "channels.x.input: 5 is outside 0..3")) << problems.size();
  EXPECT_TRUE(mentions(problems, "channels.y.mode: 'diff'"));
  EXPECT_TRUE(mentions(problems, "channels.y.range_v: 3 is not a range"));
  EXPECT_TRUE(mentions(problems, "channels.sum.range_v: single-ended inputs are +-10 V only"));
  EXPECT_TRUE(mentions(problems, "samples: 1 per reading"));
  EXPECT_TRUE(mentions(problems, "rate_hz: 20000"));
  EXPECT_TRUE(mentions(problems, "sum_threshold_v: 0 must be above 0"));
  EXPECT_TRUE(mentions(problems, "unknown key 'smaples'"));
  EXPECT_EQ(problems.size(), 8u);
}

TEST(PsdConfig, ChannelsSharingTerminalsAreRejected) {
  // Differential pair 1 uses the terminals of single-ended 1 and 5.
  const auto problems = problemsOf(R"(
channels:
  x: {mode: differential, input: 1}
  y: {mode: single_ended, input: 5}
  sum: {mode: differential, input: 1}
)");
  EXPECT_TRUE(mentions(problems, "channels.x and channels.y use the same input terminals"));
  EXPECT_TRUE(mentions(problems, "channels.x and channels.sum use the same input terminals"));
  EXPECT_TRUE(mentions(problems, "channels.y and channels.sum use the same input terminals"));
  EXPECT_EQ(problems.size(), 3u);
  EXPECT_TRUE(problemsOf(R"(
channels:
  x: {mode: single_ended, input: 0}
  y: {mode: single_ended, input: 1}
  sum: {mode: differential, input: 2}
)")
                  .empty());
}

TEST(PsdConfig, MapFileProblemsAreReported) {
  EXPECT_TRUE(
      mentions(problemsOf("map_file: a.yaml\nmap: {degree: 1}\n"), "give one of them, not both"));
  EXPECT_TRUE(mentions(problemsOf("map_file: /nonexistent/map.yaml\n"),
                       "map_file /nonexistent/map.yaml: cannot open the file"));
  EXPECT_TRUE(mentions(problemsOf("samples: many\n"), "samples: must be a whole number"));
  EXPECT_THROW(loadPsdConfig("/nonexistent/psd.yaml"), ConfigError);
}

TEST(PsdConfig, BrokenYamlIsAConfigError) {
  const std::string path = ::testing::TempDir() + "/broken-psd.yaml";
  std::ofstream(path) << "psd:\n  samples: [64\n";
  try {
    loadPsdConfig(path);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("not valid YAML"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "other: 1\n";
  EXPECT_THROW(loadPsdConfig(path), ConfigError);
  EXPECT_THROW(parsePsdConfig(YAML::Load("{[1, 2]: 3}"), "odd.yaml", "."), ConfigError);
}

TEST(PsdMapYaml, FromPartsRefusesWhatIsNotAMap) {
  const std::vector<double> three(3, 0.0);
  EXPECT_THROW(PsdMap::fromParts(0, three, three, {-1, 1, -1, 1}, 0.5), std::invalid_argument);
  EXPECT_THROW(PsdMap::fromParts(1, three, {0, 0}, {-1, 1, -1, 1}, 0.5), std::invalid_argument);
  EXPECT_THROW(PsdMap::fromParts(1, three, three, {1, -1, -1, 1}, 0.5), std::invalid_argument);
  EXPECT_THROW(PsdMap::fromParts(1, {0, 1e308, 0}, three, {-1, 1, -1, 1}, 0.5),
               std::invalid_argument);
  EXPECT_THROW(PsdMap::fromParts(1, three, three, {-1e308, 1, -1, 1}, 0.5), std::invalid_argument);
  const PsdMap map = PsdMap::fromParts(1, {0, 1, 0}, {0, 0, 1}, {-1, 1, -1, 1}, 0.5);
  VoltageReading r;
  r.x = 2.5;  // scaled by 5 V: u = 0.5
  r.sum = 1;
  EXPECT_DOUBLE_EQ(map.apply(r).u_mm, 0.5);
  EXPECT_TRUE(map.apply(r).valid);
}

TEST(PsdMapYaml, InlineMapProblemsAreReported) {
  const auto problems = problemsOf(R"(
map:
  degree: 2
  zone_mm: {u: [0.6, -0.6], v: [-0.6]}
  u: [1, 2, 3]
  v: [1, 2, 3, 4, 5, x]
)");
  EXPECT_TRUE(mentions(problems, "map.zone_mm.u: min must be below max"));
  EXPECT_TRUE(mentions(problems, "map.zone_mm.v: must be [min, max]"));
  EXPECT_TRUE(mentions(problems, "map.u: 3 coefficients; degree 2 needs 6"));
  EXPECT_TRUE(mentions(problems, "map.v[5]: must be a number"));
  EXPECT_TRUE(
      mentions(problemsOf("map: {zone_mm: {u: [0, 1], v: [0, 1]}}\n"), "map: missing 'degree'"));
}

TEST_F(FittedMap, SurvivesTheYamlRoundTripExactly) {
  const std::string yaml = psdMapToYaml(*map_, "a comment\non two lines");
  EXPECT_EQ(yaml.rfind("# a comment\n# on two lines\npsd_map:\n", 0), 0u);
  std::vector<std::string> problems;
  const auto back = psdMapFromYaml(YAML::Load(yaml)["psd_map"], "psd_map", problems);
  ASSERT_TRUE(back.has_value()) << (problems.empty() ? "" : problems.front());
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(back->zone()[k], map_->zone()[k], 1e-12);
  EXPECT_EQ(back->uCoefficients(), map_->uCoefficients());
  EXPECT_EQ(back->vCoefficients(), map_->vCoefficients());

  // The same YAML as a file, then as the config's map_file.
  const std::string dir = ::testing::TempDir();
  std::ofstream(dir + "/psd-map.yaml") << yaml;
  std::ofstream(dir + "/psd.yaml") << "psd:\n  map_file: psd-map.yaml\n";
  const PsdConfig config = loadPsdConfig(dir + "/psd.yaml");
  ASSERT_TRUE(config.map.has_value());
  EXPECT_EQ(config.map->uCoefficients(), map_->uCoefficients());
}

TEST_F(FittedMap, RecoversPositionsInTheValidZoneToTwoMicrometres) {
  EXPECT_EQ(report_->points_used, 25u * 25u);  // the +-0.6 mm part of the 0.05 mm grid
  EXPECT_NEAR(report_->u_min, -0.6, 1e-9);
  EXPECT_NEAR(report_->v_max, 0.6, 1e-9);
  // Positions off the sweep grid, read live through the rig with other noise.
  sim::SimulatedPsdRig rig(99);
  double worst = 0, sum2 = 0;
  int n = 0;
  for (double u = -0.59; u <= 0.59; u += 0.0737) {
    for (double v = -0.59; v <= 0.59; v += 0.0737) {
      rig.setSpot(sim::SpotPosition{u, v});
      const SpotPosition p = map_->apply(readAveraged(rig.daq(), rig.channels(), 64, 16000.0));
      ASSERT_TRUE(p.valid) << u << " " << v;
      const double e = std::hypot(p.u_mm - u, p.v_mm - v);
      worst = std::max(worst, e);
      sum2 += e * e;
      ++n;
    }
  }
  EXPECT_LT(worst, 0.002);
  std::printf(
      "map from the rig's sweep: fit RMS %.3f um, max %.3f um; %d live positions: RMS "
      "%.3f um, worst %.3f um\n",
      report_->rms_residual_mm * 1e3, report_->max_residual_mm * 1e3, n, std::sqrt(sum2 / n) * 1e3,
      worst * 1e3);
}

TEST_F(FittedMap, OutsideTheZoneIsMarked) {
  sim::SimulatedPsdRig rig(5);
  rig.setSpot(sim::SpotPosition{0.75, 0.0});
  const SpotPosition p = map_->apply(readAveraged(rig.daq(), rig.channels(), 64, 16000.0));
  EXPECT_TRUE(p.present);
  EXPECT_FALSE(p.valid);
}

TEST(SimulatedSweep, GridAndCsvRoundTrip) {
  sim::SimulatedPsdRig rig(3);
  sim::SweepOptions options;
  options.extent_mm = 0.2;
  options.step_mm = 0.1;
  const auto sweep = sim::simulateSweep(rig, options);
  ASSERT_EQ(sweep.size(), 25u);
  EXPECT_DOUBLE_EQ(sweep.front().u_mm, -0.2);
  EXPECT_NEAR(sweep.back().v_mm, 0.2, 1e-12);
  std::stringstream csv;
  writeSweepCsv(csv, sweep);
  const auto back = readSweepCsv(csv, "csv");
  ASSERT_EQ(back.size(), sweep.size());
  EXPECT_NEAR(back[7].x_v, sweep[7].x_v, 1e-6);
  EXPECT_NEAR(back[7].u_mm, sweep[7].u_mm, 1e-4);
  options.step_mm = 0;
  EXPECT_THROW(sim::simulateSweep(rig, options), std::invalid_argument);
}

}  // namespace
}  // namespace zerocal::psd
