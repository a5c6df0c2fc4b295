// The map in YAML (every problem at once), and the map fitted from a sweep recorded through the
// simulated rig (board, FakeTransport, Usb1408fs) recovering positions in its valid zone to 2 um.
// The PSD chain's configuration (the daq section) is tested with the daemon's configuration.
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
  EXPECT_DOUBLE_EQ(map.apply(r).spot.u_mm, 0.5);
  EXPECT_TRUE(map.apply(r).in_valid_zone);
}

TEST(PsdMapYaml, MapProblemsAreReported) {
  std::vector<std::string> problems;
  EXPECT_FALSE(psdMapFromYaml(YAML::Load(R"(
degree: 2
zone_mm: {u: [0.6, -0.6], v: [-0.6]}
u: [1, 2, 3]
v: [1, 2, 3, 4, 5, x]
)"),
                              "map", problems));
  EXPECT_TRUE(mentions(problems, "map.zone_mm.u: min must be below max"));
  EXPECT_TRUE(mentions(problems, "map.zone_mm.v: must be [min, max]"));
  EXPECT_TRUE(mentions(problems, "map.u: 3 coefficients; degree 2 needs 6"));
  EXPECT_TRUE(mentions(problems, "map.v[5]: must be a number"));
  problems.clear();
  EXPECT_FALSE(psdMapFromYaml(YAML::Load("{zone_mm: {u: [0, 1], v: [0, 1]}}"), "map", problems));
  EXPECT_TRUE(mentions(problems, "map: missing 'degree'"));
  // A degree far out of range is a problem to report, not an overflow (the fuzzer's finding).
  problems.clear();
  EXPECT_FALSE(psdMapFromYaml(YAML::Load("{degree: 62338, zone_mm: {u: [0, 1], v: [0, 1]}}"), "map",
                              problems));
  EXPECT_FALSE(problems.empty());
  EXPECT_EQ(PsdMap::termCount(62338), std::size_t{62339} * 62340 / 2);
  EXPECT_EQ(PsdMap::termCount(2), 6u);
  EXPECT_EQ(PsdMap::termCount(-1), 0u);
}

TEST(PsdMapYaml, MapFileProblemsAreConfigErrors) {
  EXPECT_THROW(loadPsdMap("/nonexistent/map.yaml"), ConfigError);
  const std::string path = ::testing::TempDir() + "/broken-map.yaml";
  std::ofstream(path) << "psd_map:\n  degree: [7\n";
  try {
    loadPsdMap(path);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("not valid YAML"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "other: 1\n";
  EXPECT_THROW(loadPsdMap(path), ConfigError);
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

  // The same YAML as a file, as daq.map_file names it.
  const std::string path = ::testing::TempDir() + "/psd-map.yaml";
  std::ofstream(path) << yaml;
  EXPECT_EQ(loadPsdMap(path).uCoefficients(), map_->uCoefficients());
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
      rig.setSpot(PsdSpot{u, v});
      const PsdReading p =
          map_->apply(usb1408fs::readAveraged(rig.daq(), rig.channels(), 64, 16000.0));
      ASSERT_TRUE(p.in_valid_zone) << u << " " << v;
      const double e = std::hypot(p.spot.u_mm - u, p.spot.v_mm - v);
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
  rig.setSpot(PsdSpot{0.75, 0.0});
  const PsdReading p = map_->apply(usb1408fs::readAveraged(rig.daq(), rig.channels(), 64, 16000.0));
  EXPECT_TRUE(p.spot_present);
  EXPECT_FALSE(p.in_valid_zone);
}

TEST(SimulatedSweep, GridAndCsvRoundTrip) {
  sim::SimulatedPsdRig rig(3);
  sim::SweepOptions options;
  options.extent_mm = 0.2;
  options.step_mm = 0.1;
  const auto sweep = sim::simulateSweep(rig, options);
  ASSERT_EQ(sweep.size(), 25u);
  EXPECT_DOUBLE_EQ(sweep.front().spot.u_mm, -0.2);
  EXPECT_NEAR(sweep.back().spot.v_mm, 0.2, 1e-12);
  std::stringstream csv;
  writeSweepCsv(csv, sweep);
  const auto back = readSweepCsv(csv, "csv");
  ASSERT_EQ(back.size(), sweep.size());
  EXPECT_NEAR(back[7].x_v, sweep[7].x_v, 1e-6);
  EXPECT_NEAR(back[7].spot.u_mm, sweep[7].spot.u_mm, 1e-4);
  options.step_mm = 0;
  EXPECT_THROW(sim::simulateSweep(rig, options), std::invalid_argument);
}

}  // namespace
}  // namespace zerocal::psd
