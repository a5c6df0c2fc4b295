// The PSD chain on the simulated PSD and board: averaging with standard errors, spot presence,
// and a map fitted from a simulated stage sweep that recovers positions to 2 um.
#include "zerocal/psd/psd.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>

#include "zerocal/error.h"
#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"

namespace zerocal::psd {
namespace {

using sim::PsdModel;
using sim::PsdModelOptions;

TEST(SpotDetector, HysteresisOnSum) {
  SpotDetector detector(0.5, 0.4);
  VoltageReading r;
  r.sum = 0.45;
  EXPECT_FALSE(detector.update(r));
  r.sum = 0.55;
  EXPECT_TRUE(detector.update(r));
  r.sum = 0.45;
  EXPECT_TRUE(detector.update(r));
  r.sum = 0.3;
  EXPECT_FALSE(detector.update(r));
}

TEST(SweepCsv, ReadsNamedColumnsAndReportsEveryBadLine) {
  std::istringstream good(
      "x_v, y_v,sum_v,u_mm,v_mm,note\n1,2,3,0.1,0.2,a\n\n-1,-2,3.5,-0.1,-0.2,b\n");
  const auto sweep = readSweepCsv(good, "good.csv");
  ASSERT_EQ(sweep.size(), 2u);
  EXPECT_DOUBLE_EQ(sweep[0].spot.u_mm, 0.1);
  EXPECT_DOUBLE_EQ(sweep[1].x_v, -1);
  EXPECT_DOUBLE_EQ(sweep[1].sum_v, 3.5);
  std::istringstream bad("u_mm,v_mm,x_v,y_v,sum_v\n1,2,x,4,5\n1,2,3,4\n");
  try {
    readSweepCsv(bad, "bad.csv");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 2: x_v is not a number"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("line 3: sum_v is not a number"), std::string::npos);
  }
  std::istringstream no_column("u_mm,v_mm,x_v\n");
  EXPECT_THROW(readSweepCsv(no_column, "short.csv"), InputError);
}

// A sweep like the paper's: the stage moves the spot over a grid, 64 samples averaged per point.
std::vector<SweepPoint> simulatedSweep(PsdModel& psd, double half_width, double step) {
  std::vector<SweepPoint> sweep;
  const int n = static_cast<int>(std::lround(2 * half_width / step));
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const PsdSpot p{-half_width + i * step, -half_width + j * step};
      SweepPoint s{p, 0, 0, 0};
      for (int k = 0; k < 64; ++k) {
        const sim::PsdVoltages v = psd.measure(p);
        s.x_v += v.x / 64;
        s.y_v += v.y / 64;
        s.sum_v += v.sum / 64;
      }
      sweep.push_back(s);
    }
  }
  return sweep;
}

VoltageReading readingAt(const PsdModel& psd, double u, double v) {
  const sim::PsdVoltages ideal = psd.ideal(PsdSpot{u, v});
  VoltageReading r;
  r.x = ideal.x;
  r.y = ideal.y;
  r.sum = ideal.sum;
  r.x_se = r.y_se = 0.005 / 8;
  r.samples = 64;
  return r;
}

class PsdMapTest : public ::testing::Test {
 protected:
  PsdMapTest() : sweep_(simulatedSweep(psd_, 0.8, 0.04)) {
    map_ = PsdMap::fit(sweep_, MapFitOptions{}, &report_);
  }
  PsdModel psd_;
  std::vector<SweepPoint> sweep_;
  MapFitReport report_;
  PsdMap map_;
};

TEST_F(PsdMapTest, RecoversPositionsInTheValidZoneToTwoMicrometres) {
  EXPECT_GT(report_.points_used, 900u);
  EXPECT_LT(report_.rms_residual_mm, 0.002);
  EXPECT_NEAR(report_.u_min, -0.6, 1e-9);
  EXPECT_NEAR(report_.v_max, 0.6, 1e-9);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-0.6, 0.6);
  double worst = 0;
  for (int k = 0; k < 300; ++k) {
    const double u = coord(rng), v = coord(rng);
    const PsdReading p = map_.apply(readingAt(psd_, u, v));
    ASSERT_TRUE(p.spot_present);
    ASSERT_TRUE(p.in_valid_zone) << u << " " << v;
    worst = std::max(worst, std::hypot(p.spot.u_mm - u, p.spot.v_mm - v));
  }
  EXPECT_LT(worst, 0.002);
  std::printf("map: %zu points, rms residual %.3f um, worst recovery error %.3f um\n",
              report_.points_used, report_.rms_residual_mm * 1e3, worst * 1e3);
  const PsdReading centre = map_.apply(readingAt(psd_, 0, 0));
  EXPECT_NEAR(centre.se.u_mm, 0.005 / 8 / 5.0, 0.00005);  // noise / sqrt(64) / (5 V/mm)
}

TEST_F(PsdMapTest, OutsideTheZoneOrWithoutLightIsMarked) {
  const PsdReading outside = map_.apply(readingAt(psd_, 0.9, 0.0));
  EXPECT_TRUE(outside.spot_present);
  EXPECT_FALSE(outside.in_valid_zone);
  VoltageReading dark = readingAt(psd_, 0, 0);
  dark.sum = 0.01;
  const PsdReading none = map_.apply(dark);
  EXPECT_FALSE(none.spot_present);
  EXPECT_FALSE(none.in_valid_zone);
}

TEST_F(PsdMapTest, SerialisesAndParsesBack) {
  const PsdMap copy = PsdMap::parse(map_.serialize());
  const VoltageReading r = readingAt(psd_, 0.31, -0.22);
  EXPECT_DOUBLE_EQ(copy.apply(r).spot.u_mm, map_.apply(r).spot.u_mm);
  EXPECT_DOUBLE_EQ(copy.apply(r).spot.v_mm, map_.apply(r).spot.v_mm);
  EXPECT_THROW(PsdMap::parse("zerocal-psd-map 1\ndegree 3\n"), InputError);
  EXPECT_THROW(PsdMap::parse("nonsense"), InputError);
}

// The fingerprint names the map, not its file: a copy has the same, a map differing in one
// coefficient another.
TEST_F(PsdMapTest, TheFingerprintNamesTheMapItself) {
  const std::string fingerprint = map_.fingerprint();
  EXPECT_EQ(fingerprint.size(), 16u);
  EXPECT_EQ(fingerprint.find_first_not_of("0123456789abcdef"), std::string::npos);
  EXPECT_EQ(PsdMap::parse(map_.serialize()).fingerprint(), fingerprint);
  std::vector<double> u = map_.uCoefficients();
  u[1] *= 1.0 + 1e-9;
  const PsdMap other =
      PsdMap::fromParts(map_.degree(), u, map_.vCoefficients(), map_.zone(), map_.minSumV());
  EXPECT_NE(other.fingerprint(), fingerprint);
}

TEST(PsdMapFit, TooFewPointsIsAnInputError) {
  std::vector<SweepPoint> sweep(5, SweepPoint{0, 0, 0, 0, 3});
  EXPECT_THROW(PsdMap::fit(sweep, MapFitOptions{}), InputError);
}

}  // namespace
}  // namespace zerocal::psd
