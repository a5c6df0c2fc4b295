// The simulated PSD: shape of the response the paper describes, noise, and the path through the
// simulated USB-1408FS into the driver.
#include "zerocal/sim/psd_model.h"

#include <gtest/gtest.h>

#include <cmath>

#include "zerocal/sim/fake_transport.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::sim {
namespace {

using namespace std::chrono_literals;

TEST(PsdModel, AboutFiveVoltsPerMillimetreNearTheCentre) {
  PsdModel psd;
  EXPECT_NEAR(psd.ideal(PsdSpot{0, 0}).x, 0.0, 1e-12);
  EXPECT_NEAR(psd.ideal(PsdSpot{0.02, 0}).x, 0.1, 0.002);  // 0.1 V per 20 um
  EXPECT_NEAR(psd.ideal(PsdSpot{0, -0.02}).y, -0.1, 0.002);
  for (double u = -0.6; u <= 0.6; u += 0.05) {
    const double x = psd.ideal(PsdSpot{u, 0.1}).x;
    EXPECT_NEAR(x, 5.0 * u, 0.2 * std::abs(5.0 * u) + 1e-9) << u;  // nearly linear
  }
}

TEST(PsdModel, MonotonicThenSaturating) {
  PsdModel psd;
  double last = -1e9;
  for (double u = -1.5; u <= 1.5; u += 0.01) {
    const double x = psd.ideal(PsdSpot{u, -0.2}).x;
    EXPECT_GT(x, last) << u;
    last = x;
  }
  const double x2 = psd.ideal(PsdSpot{2, 0}).x, x3 = psd.ideal(PsdSpot{3, 0}).x;
  EXPECT_LT(std::abs(x3 - x2), 0.05);
  EXPECT_LT(x3, 5.0 * 1.0);
}

TEST(PsdModel, SumFallsToNothingOffTheDetector) {
  PsdModel psd;
  const double centre = psd.ideal(PsdSpot{0, 0}).sum;
  EXPECT_GT(centre, 3.0);
  EXPECT_GT(psd.ideal(PsdSpot{3, 0}).sum, 0.95 * centre);
  EXPECT_LT(psd.ideal(PsdSpot{5.0, 0}).sum, 0.6 * centre);
  EXPECT_LT(psd.ideal(PsdSpot{0, -7.0}).sum, 0.01 * centre);
  EXPECT_LT(std::abs(psd.ideal(PsdSpot{0, -7.0}).y), 0.2);
  const PsdVoltages dark = psd.ideal(std::nullopt);
  EXPECT_EQ(dark.sum, 0.0);
  EXPECT_EQ(dark.x, 0.0);
}

TEST(PsdModel, SeededNoiseOfAboutTenMillivolts) {
  PsdModel a, b;
  double sum = 0, sum2 = 0, worst = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double x = a.measure(PsdSpot{0.1, 0}).x - a.ideal(PsdSpot{0.1, 0}).x;
    sum += x;
    sum2 += x * x;
    worst = std::max(worst, std::abs(x));
  }
  EXPECT_NEAR(std::sqrt(sum2 / n - (sum / n) * (sum / n)), 0.005, 0.0003);
  EXPECT_LT(worst, 0.03);
  EXPECT_EQ(PsdModel().measure(PsdSpot{0, 0}).x, b.measure(PsdSpot{0, 0}).x);
}

TEST(PsdModel, FeedsTheSimulatedBoardAndTheDriverReadsIt) {
  PsdModelOptions options;
  options.noise_rms_v = 0.0;
  PsdModel psd(options);
  const PsdSpot spot{0.21, -0.33};
  Usb1408fsModel board;
  board.setAnalogSource(psdAnalogSource(psd, [&](double) { return spot; }));
  usb1408fs::Usb1408fs dev(FakeTransport::opener(board));
  const PsdWiring wiring;
  const PsdVoltages expected = psd.ideal(spot);
  const double lsb = 5.0 / 8191.0;
  EXPECT_NEAR(dev.readVolts(wiring.x), expected.x, lsb);
  EXPECT_NEAR(dev.readVolts(wiring.y), expected.y, lsb);
  EXPECT_NEAR(dev.readVolts(wiring.sum), expected.sum, lsb);
  EXPECT_NEAR(dev.readVolts({3, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip1V}),
              0.0, 1.0 / 8191.0);
}

}  // namespace
}  // namespace zerocal::sim
