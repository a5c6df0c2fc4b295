// The USB-1408FS's part of the PSD chain on the simulated PSD and board: averaging with standard
// errors, a loss discarding its block, one-shot and continuous readings.
#include "zerocal/usb1408fs/psd_chain.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"

namespace zerocal::usb1408fs {
namespace {

using sim::PsdModel;

TEST(BlockAverager, MeansAndStandardErrorsPerChannel) {
  BlockAverager averager(4);
  // x, y, sum interleaved; 4 scans -> one reading.
  const double volts[12] = {1, 10, 3, 2, 10, 3, 3, 10, 3, 4, 10, 3};
  ScanBlock block;
  block.volts = volts;
  block.count = 12;
  averager.onScanData(block);
  VoltageReading r;
  ASSERT_TRUE(averager.take(r));
  EXPECT_FALSE(averager.take(r));
  EXPECT_DOUBLE_EQ(r.x, 2.5);
  EXPECT_DOUBLE_EQ(r.y, 10.0);
  EXPECT_DOUBLE_EQ(r.sum, 3.0);
  EXPECT_NEAR(r.x_se, std::sqrt((1.25 * 4 / 3) / 4), 1e-12);  // sample std / sqrt(n)
  EXPECT_DOUBLE_EQ(r.y_se, 0.0);
  EXPECT_EQ(r.samples, 4u);
}

TEST(BlockAverager, ALossDiscardsThePartialBlock) {
  BlockAverager averager(2);
  const double volts[6] = {1, 1, 1, 1, 1, 1};
  ScanBlock block;
  block.volts = volts;
  block.count = 4;
  averager.onScanData(block);
  averager.onPacketsLost(1, 3);
  block.first_channel = 1;  // resumes mid-scan after the hole
  block.count = 2;
  averager.onScanData(block);
  VoltageReading r;
  EXPECT_FALSE(averager.take(r));
  EXPECT_EQ(averager.blocksDiscarded(), 1u);
}

TEST(ReadAveraged, SixtyFourSamplesThroughTheSimulatedBoard) {
  PsdModel psd;
  const PsdSpot spot{0.12, -0.05};
  sim::Usb1408fsModel board;
  board.setAnalogSource(sim::psdAnalogSource(psd, [&](double) { return spot; }));
  Usb1408fs daq(sim::FakeTransport::opener(board));
  const VoltageReading r = readAveraged(daq, PsdChannels{}, 64, 16000.0);
  const sim::PsdVoltages ideal = PsdModel().ideal(spot);
  EXPECT_EQ(r.samples, 64u);
  EXPECT_NEAR(r.x, ideal.x, 4 * r.x_se + 0.001);
  EXPECT_NEAR(r.y, ideal.y, 4 * r.y_se + 0.001);
  EXPECT_NEAR(r.sum, ideal.sum, 4 * r.sum_se + 0.001);
  EXPECT_NEAR(r.x_se, 0.005 / 8, 0.0003);  // noise / sqrt(64)
  EXPECT_FALSE(daq.scanning());
}

TEST(PsdStream, AReadingEveryFourMillisecondsAtSixteenKilohertz) {
  PsdModel psd;
  sim::Usb1408fsModel board;
  board.setAnalogSource(sim::psdAnalogSource(psd, [](double) { return PsdSpot{-0.3, 0.2}; }));
  Usb1408fs daq(sim::FakeTransport::opener(board));
  const sim::PsdVoltages ideal = PsdModel().ideal(PsdSpot{-0.3, 0.2});
  {
    PsdStream stream(daq, PsdChannels{}, 64, 16000.0);
    VoltageReading r;
    ASSERT_TRUE(stream.next(r, std::chrono::milliseconds(10)));
    auto t0 = board.now();
    for (int k = 0; k < 10; ++k) {
      ASSERT_TRUE(stream.next(r, std::chrono::milliseconds(10)));
      EXPECT_NEAR(r.x, ideal.x, 4 * r.x_se + 0.001);
    }
    const double per_reading_ms =
        std::chrono::duration<double, std::milli>(board.now() - t0).count() / 10;
    EXPECT_LT(per_reading_ms, 5.0);
    EXPECT_GT(per_reading_ms, 3.5);
    EXPECT_EQ(stream.blocksDiscarded(), 0u);
  }
  EXPECT_FALSE(daq.scanning());
}

}  // namespace
}  // namespace zerocal::usb1408fs
