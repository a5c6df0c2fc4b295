// The protocol layer against the simulated board through FakeTransport: every command's bytes,
// both conversions, calibration, scans with gaps, and each failure a technician may see.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>

#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/usb1408fs_model.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::usb1408fs {
namespace {

using sim::FakeTransport;
using sim::Usb1408fsModel;
using ::testing::ElementsAre;
using ::testing::ElementsAreArray;
using ::testing::HasSubstr;
using namespace std::chrono_literals;

using Bytes = std::vector<std::uint8_t>;

Channel diff(int c, Range r) { return {c, InputMode::kDifferential, r}; }
Channel se(int c) { return {c, InputMode::kSingleEnded, Range::kBip10V}; }

// Distinct, channel-dependent inputs so that a swapped channel or range shows.
double testVolts(const Channel& ch, double /*t*/) {
  if (ch.mode == InputMode::kSingleEnded) return -4.2 + 0.9 * ch.number;
  return 0.63 * fullScaleVolts(ch) * (ch.number % 2 == 0 ? 1.0 : -1.0) + 0.01 * ch.number;
}

double lsb(const Channel& ch) { return fullScaleVolts(ch) / 8191.0; }

class Usb1408fsTest : public ::testing::Test {
 protected:
  Usb1408fsTest() { model_.setAnalogSource(testVolts); }

  Usb1408fs& open() {
    dev_ = std::make_unique<Usb1408fs>(FakeTransport::opener(model_));
    model_.clearCommandLog();
    return *dev_;
  }
  // The data bytes of the last command the board received, after checking its setup packet.
  Bytes lastCommand() const {
    const auto& log = model_.commandLog();
    EXPECT_FALSE(log.empty());
    if (log.empty()) return {};
    const auto& c = log.back();
    EXPECT_EQ(c.request_type, 0x21);
    EXPECT_EQ(c.request, 0x09);
    EXPECT_EQ(c.value, 0x0200 | c.data.at(0));
    EXPECT_EQ(c.index, 0);
    return c.data;
  }

  Usb1408fsModel model_;
  std::unique_ptr<Usb1408fs> dev_;
};

class Collector : public ScanConsumer {
 public:
  explicit Collector(std::size_t channels) : values(channels) {}
  void onScanData(const ScanBlock& block) noexcept override {
    for (std::size_t i = 0; i < block.count; ++i) {
      values[(block.first_channel + i) % values.size()].push_back(block.volts[i]);
    }
    ++blocks;
  }
  void onPacketsLost(std::uint32_t n, std::uint16_t index) noexcept override {
    losses.emplace_back(n, index);
  }
  std::vector<std::vector<double>> values;
  std::vector<std::pair<std::uint32_t, std::uint16_t>> losses;
  int blocks = 0;
};

// ---- Conversions --------------------------------------------------------------------------

TEST(Conversion, DifferentialIsSigned14BitInTheTopBits) {
  EXPECT_EQ(differentialCode(0x0000), 0);
  EXPECT_EQ(differentialCode(0x7FFC), 8191);
  EXPECT_EQ(differentialCode(0x8000), -8192);
  EXPECT_EQ(differentialCode(0xFFFC), -1);
  EXPECT_EQ(differentialCode(0x0004), 1);
}

TEST(Conversion, SingleEndedFollowsTheFirmwareQuirks) {
  EXPECT_EQ(singleEndedCode(0x4000), 0);  // mid-scale
  EXPECT_EQ(singleEndedCode(0x0000), -8192);
  EXPECT_EQ(singleEndedCode(0x4002), 1);
  EXPECT_EQ(singleEndedCode(0x7FF8), 0x3FFC - 0x2000);
  EXPECT_EQ(singleEndedCode(0x7FFA), 8191);  // 0x7ff9..0x7ffc read as full scale
  EXPECT_EQ(singleEndedCode(0x7FFC), 8191);
  EXPECT_EQ(singleEndedCode(0x7FFD), -8192);  // above 0x7ffc reads as 0
  EXPECT_EQ(singleEndedCode(0xFFFE), -8192);
}

TEST(Conversion, VoltsPerRange) {
  const double expected[8] = {20, 10, 5, 4, 2.5, 2, 1.25, 1};
  for (int r = 0; r < 8; ++r) {
    EXPECT_DOUBLE_EQ(codeToVolts(8191, diff(0, static_cast<Range>(r))), expected[r]);
  }
  EXPECT_DOUBLE_EQ(codeToVolts(-8191, se(3)), -10.0);
  EXPECT_EQ(wireChannel(se(3)), 11);
  EXPECT_EQ(wireRange(se(3)), 0);
  EXPECT_EQ(calibrationAddress(diff(2, Range::kBip4V)), 0x200 + (2 * 8 + 3) * 8);
  EXPECT_EQ(calibrationAddress(se(7)), 0x300 + 7 * 8);
}

TEST(Pacer, SmallestPrescaleThatFits) {
  Pacer p = computePacer(1000.0);
  EXPECT_EQ(p.prescale, 0);
  EXPECT_EQ(p.preload, 10000);
  EXPECT_DOUBLE_EQ(p.actual_rate_hz, 1000.0);
  p = computePacer(100.0);  // 100000 does not fit 16 bits
  EXPECT_EQ(p.prescale, 1);
  EXPECT_EQ(p.preload, 50000);
  p = computePacer(48000.0);
  EXPECT_EQ(p.prescale, 0);
  EXPECT_EQ(p.preload, 208);
  EXPECT_NEAR(p.actual_rate_hz, 48076.92, 0.01);
  p = computePacer(1.0);
  EXPECT_EQ(p.prescale, 8);
  EXPECT_EQ(p.preload, 39063);
  EXPECT_THROW(computePacer(0.5), ProtocolError);
  EXPECT_THROW(computePacer(0.0), ProtocolError);
  EXPECT_THROW(computePacer(-5.0), ProtocolError);
}

// ---- Commands -----------------------------------------------------------------------------

TEST_F(Usb1408fsTest, OpenReadsTheCalibrationTableOnceIn62ByteRequests) {
  Usb1408fs dev(FakeTransport::opener(model_));
  const auto& log = model_.commandLog();
  ASSERT_EQ(log.size(), 6u);  // 0x140 bytes = 5 x 62 + 10
  for (std::size_t i = 0; i < log.size(); ++i) {
    const std::uint16_t address = static_cast<std::uint16_t>(0x200 + 62 * i);
    const std::uint8_t count = i < 5 ? 62 : 10;
    EXPECT_THAT(log[i].data, ElementsAre(0x30, address & 0xFF, address >> 8, 0x00, count));
    EXPECT_EQ(log[i].value, 0x0230);
  }
  EXPECT_EQ(model_.memoryWriteAttempts(), 0);
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 8; ++r) {
      const Channel ch = diff(c, static_cast<Range>(r));
      EXPECT_DOUBLE_EQ(dev.calibration(ch).slope, model_.calibration(ch).slope);
      EXPECT_DOUBLE_EQ(dev.calibration(ch).intercept, model_.calibration(ch).intercept);
    }
  }
  EXPECT_DOUBLE_EQ(dev.calibration(se(5)).slope, model_.calibration(se(5)).slope);
}

TEST_F(Usb1408fsTest, AinBytesDifferentialAndSingleEnded) {
  auto& dev = open();
  dev.readRaw(diff(2, Range::kBip5V));
  EXPECT_THAT(lastCommand(), ElementsAre(0x10, 2, 2));
  dev.readRaw(se(5));
  EXPECT_THAT(lastCommand(), ElementsAre(0x10, 13, 0));
  EXPECT_THROW(dev.readRaw(diff(4, Range::kBip1V)), ProtocolError);
  EXPECT_THROW(dev.readRaw(se(8)), ProtocolError);
}

TEST_F(Usb1408fsTest, ReadVoltsEveryRangeWithCalibration) {
  auto& dev = open();
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 8; ++r) {
      const Channel ch = diff(c, static_cast<Range>(r));
      EXPECT_NEAR(dev.readVolts(ch), testVolts(ch, 0), 0.51 * lsb(ch) * 1.05) << c << " " << r;
    }
  }
  for (int c = 0; c < 8; ++c) {
    EXPECT_NEAR(dev.readVolts(se(c)), testVolts(se(c), 0), lsb(se(c)) * 1.05) << c;
  }
}

TEST_F(Usb1408fsTest, ForgettingTheCalibrationWouldBeFarOff) {
  auto& dev = open();
  const Channel ch = diff(1, Range::kBip10V);
  const double uncalibrated = codeToVolts(differentialCode(dev.readRaw(ch)), ch);
  EXPECT_GT(std::abs(uncalibrated - testVolts(ch, 0)), 0.01);
  EXPECT_NEAR(dev.readVolts(ch), testVolts(ch, 0), lsb(ch));
}

TEST_F(Usb1408fsTest, StatusBlinkAndDigitalBytes) {
  auto& dev = open();
  model_.setStatus(0x0005);
  EXPECT_EQ(dev.status(), 0x0005);
  EXPECT_THAT(lastCommand(), ElementsAre(0x44, 0, 0));  // the full report, as the C driver sends
  dev.blinkLed();
  EXPECT_THAT(lastCommand(), ElementsAre(0x40));
  EXPECT_EQ(model_.blinkCount(), 1);
  dev.configureDigitalPort(DigitalPort::kB, DigitalDirection::kOutput);
  EXPECT_THAT(lastCommand(), ElementsAre(0x01, 1, 0));
  dev.writeDigital(DigitalPort::kB, 0xA5);
  EXPECT_THAT(lastCommand(), ElementsAre(0x04, 1, 0xA5));
  EXPECT_EQ(model_.digitalOutput(1), 0xA5);
  model_.setDigitalInputs(0x3C, 0x00);
  EXPECT_THAT(dev.readDigital(), ElementsAre(0x3C, 0xA5));
  EXPECT_THAT(lastCommand(), ElementsAre(0x03));
}

TEST_F(Usb1408fsTest, LoadQueueSends18Bytes) {
  auto& dev = open();
  dev.loadQueue({diff(3, Range::kBip2V), se(6)});
  EXPECT_THAT(lastCommand(),
              ElementsAreArray(Bytes{0x13, 2, 3, 5, 14, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_THROW(dev.loadQueue({}), ProtocolError);
  EXPECT_THROW(dev.loadQueue(std::vector<Channel>(9, se(0))), ProtocolError);
}

// ---- Scans --------------------------------------------------------------------------------

TEST_F(Usb1408fsTest, ScanCommandBytes) {
  auto& dev = open();
  Collector sink(2);
  ScanConfig config{{se(2), se(3)}, 1000.0, 100};
  const Pacer pacer = dev.startScan(config, sink);
  EXPECT_EQ(pacer.preload, 10000);
  const auto& log = model_.commandLog();
  ASSERT_EQ(log.size(), 2u);
  EXPECT_THAT(log[0].data,
              ElementsAreArray(Bytes{0x13, 2, 10, 0, 11, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}));
  // lowchan 10, highchan 11 (channel numbers, single-ended c is c + 8; not queue positions 0, 1),
  // count 200 samples, prescale 0, preload 10000, options: single execution + queue.
  EXPECT_THAT(log[1].data, ElementsAre(0x11, 10, 11, 200, 0, 0, 0, 0, 0x10, 0x27, 0x11));
  dev.stopScan();
  EXPECT_THAT(lastCommand(), ElementsAre(0x12));
}

TEST_F(Usb1408fsTest, SingleExecutionScanDeliversCalibratedSamplesPerChannel) {
  auto& dev = open();
  const std::vector<Channel> channels = {diff(1, Range::kBip10V), diff(2, Range::kBip1V),
                                         diff(3, Range::kBip2V)};
  Collector sink(channels.size());
  dev.startScan({channels, 2000.0, 100}, sink);
  for (int i = 0; i < 100 && !dev.scanComplete(); ++i) dev.pollScan(20ms);
  ASSERT_TRUE(dev.scanComplete());
  for (std::size_t c = 0; c < channels.size(); ++c) {
    ASSERT_EQ(sink.values[c].size(), 100u);
    for (double v : sink.values[c]) EXPECT_NEAR(v, testVolts(channels[c], 0), lsb(channels[c]));
  }
  EXPECT_EQ(dev.scanStats().samples, 300u);
  EXPECT_EQ(dev.scanStats().packets, 10u);  // ceil(300 / 31)
  EXPECT_EQ(dev.scanStats().lost_packets, 0u);
  dev.stopScan();
  EXPECT_FALSE(model_.scanning());
}

TEST_F(Usb1408fsTest, ScanGapsAreDetectedAndChannelPhaseKept) {
  auto& dev = open();
  const std::vector<Channel> channels = {diff(0, Range::kBip10V), diff(1, Range::kBip10V),
                                         diff(2, Range::kBip5V)};
  Collector sink(channels.size());
  model_.dropScanPackets(5, 3);
  model_.dropScanPackets(20, 1);
  dev.startScan({channels, 10000.0, 0}, sink);
  while (dev.scanStats().packets < 40) dev.pollScan(10ms);
  dev.stopScan();
  EXPECT_THAT(sink.losses, ElementsAre(std::make_pair(3u, std::uint16_t{8}),
                                       std::make_pair(1u, std::uint16_t{21})));
  EXPECT_EQ(dev.scanStats().lost_packets, 4u);
  EXPECT_EQ(dev.scanStats().gaps, 2u);
  for (std::size_t c = 0; c < channels.size(); ++c) {
    for (double v : sink.values[c]) ASSERT_NEAR(v, testVolts(channels[c], 0), lsb(channels[c]));
  }
}

// Completes packet k+1 before packet k every few packets, as independent endpoints may.
class ReorderingTransport final : public UsbTransport, public StreamSink {
 public:
  explicit ReorderingTransport(Usb1408fsModel& model) : inner_(model) {}
  void controlOut(std::uint8_t rt, std::uint8_t r, std::uint16_t v, std::uint16_t i,
                  const std::uint8_t* d, std::size_t n, std::chrono::milliseconds t) override {
    inner_.controlOut(rt, r, v, i, d, n, t);
  }
  std::size_t interruptIn(std::uint8_t ep, std::uint8_t* d, std::size_t n,
                          std::chrono::milliseconds t) override {
    return inner_.interruptIn(ep, d, n, t);
  }
  void startStream(const std::uint8_t* eps, std::size_t count, std::size_t per, std::size_t size,
                   StreamSink& sink) override {
    sink_ = &sink;
    inner_.startStream(eps, count, per, size, *this);
  }
  void pollStream(std::chrono::milliseconds t) override { inner_.pollStream(t); }
  void stopStream() noexcept override { inner_.stopStream(); }
  void onPacket(std::uint8_t ep, const std::uint8_t* data, std::size_t length,
                TransferStatus status) noexcept override {
    if (status == TransferStatus::kCompleted && !holding_ && ++seen_ % 4 == 1) {
      std::memcpy(held_, data, length);
      holding_ = true;
      return;
    }
    sink_->onPacket(ep, data, length, status);
    if (holding_) {
      holding_ = false;
      sink_->onPacket(ep, held_, sizeof held_, TransferStatus::kCompleted);
    }
  }

 private:
  sim::FakeTransport inner_;
  StreamSink* sink_ = nullptr;
  std::uint8_t held_[64] = {};
  bool holding_ = false;
  int seen_ = 0;
};

TEST_F(Usb1408fsTest, PacketsOvertakingEachOtherAreReorderedNotLost) {
  Usb1408fs dev([this]() -> std::unique_ptr<UsbTransport> {
    return std::make_unique<ReorderingTransport>(model_);
  });
  const std::vector<Channel> channels = {diff(0, Range::kBip10V), diff(1, Range::kBip4V),
                                         diff(2, Range::kBip1V)};
  Collector sink(channels.size());
  model_.dropScanPackets(10, 1);
  dev.startScan({channels, 4000.0, 0}, sink);
  while (dev.scanStats().packets < 60) dev.pollScan(10ms);
  dev.stopScan();
  EXPECT_EQ(dev.scanStats().lost_packets, 1u);  // only the one really dropped
  EXPECT_EQ(dev.scanStats().late_packets, 0u);
  for (std::size_t c = 0; c < channels.size(); ++c) {
    for (double v : sink.values[c]) ASSERT_NEAR(v, testVolts(channels[c], 0), lsb(channels[c]));
  }
}

TEST_F(Usb1408fsTest, ScanIndexWrapsWithoutFalseGaps) {
  auto& dev = open();
  Collector sink(1);
  dev.startScan({{se(0)}, 50000.0, 0}, sink);
  while (dev.scanStats().packets < 66000) dev.pollScan(100ms);
  dev.stopScan();
  EXPECT_EQ(dev.scanStats().lost_packets, 0u);
}

TEST_F(Usb1408fsTest, StopThenStartAgain) {
  auto& dev = open();
  Collector sink(1);
  dev.startScan({{se(1)}, 1000.0, 0}, sink);
  dev.pollScan(100ms);
  dev.stopScan();
  EXPECT_FALSE(dev.scanning());
  EXPECT_FALSE(model_.scanning());
  Collector again(1);
  dev.startScan({{se(1)}, 1000.0, 62}, again);
  while (!dev.scanComplete()) dev.pollScan(50ms);
  EXPECT_EQ(again.values[0].size(), 62u);
  EXPECT_EQ(dev.scanStats().lost_packets, 0u);
}

// ---- Failures -----------------------------------------------------------------------------

TEST_F(Usb1408fsTest, UnpluggedMidScanThenReopenWhenBack) {
  auto& dev = open();
  Collector sink(1);
  dev.startScan({{se(0)}, 1000.0, 0}, sink);
  dev.pollScan(100ms);
  model_.unplug();
  try {
    for (int i = 0; i < 10; ++i) dev.pollScan(10ms);
    FAIL() << "no DisconnectedError";
  } catch (const DisconnectedError& e) {
    EXPECT_THAT(e.what(), HasSubstr("unplugged during the scan"));
    EXPECT_THAT(e.what(), HasSubstr("LIBUSB_ERROR_NO_DEVICE"));
    EXPECT_THAT(e.what(), HasSubstr("reopen"));
  }
  EXPECT_FALSE(dev.connected());
  EXPECT_FALSE(dev.scanning());
  EXPECT_THROW(dev.readVolts(se(0)), DisconnectedError);
  try {
    dev.reopen();
    FAIL() << "reopened an absent board";
  } catch (const DeviceNotFoundError& e) {
    EXPECT_THAT(e.what(), HasSubstr("09db:00a1"));
    EXPECT_THAT(e.what(), HasSubstr("config/udev/60-zerocal-usb1408fs.rules"));
  }
  model_.replug();
  dev.reopen();
  EXPECT_TRUE(dev.connected());
  EXPECT_NEAR(dev.readVolts(se(0)), testVolts(se(0), 0), lsb(se(0)));
}

TEST_F(Usb1408fsTest, UnpluggedBetweenCommands) {
  auto& dev = open();
  model_.unplug();
  try {
    dev.status();
    FAIL();
  } catch (const DisconnectedError& e) {
    EXPECT_THAT(e.what(), HasSubstr("LIBUSB_ERROR_NO_DEVICE"));
  }
  EXPECT_FALSE(dev.connected());
}

TEST_F(Usb1408fsTest, ResetDropsTheBoardOffTheBus) {
  auto& dev = open();
  const std::uint8_t reset[1] = {cmd::kReset};
  model_.controlOut(0x21, 0x09, 0x0241, 0, reset, 1);
  EXPECT_EQ(model_.resets(), 1);
  EXPECT_THROW(dev.blinkLed(), DisconnectedError);
  model_.replug();
  dev.reopen();
  dev.blinkLed();
}

TEST_F(Usb1408fsTest, StallNamesTheCommand) {
  auto& dev = open();
  model_.stallNextCommand(cmd::kAIn);
  try {
    dev.readRaw(diff(0, Range::kBip1V));
    FAIL();
  } catch (const StallError& e) {
    EXPECT_THAT(e.what(), HasSubstr("AIN (0x10)"));
    EXPECT_THAT(e.what(), HasSubstr("STALL"));
  }
  EXPECT_NO_THROW(dev.readRaw(diff(0, Range::kBip1V)));
}

TEST_F(Usb1408fsTest, MissingReplyTimesOut) {
  auto& dev = open();
  model_.muteNextReplies(1);
  try {
    dev.status();
    FAIL();
  } catch (const TimeoutError& e) {
    EXPECT_THAT(e.what(), HasSubstr("no reply from the USB-1408FS to GET_STATUS (0x44)"));
    EXPECT_THAT(e.what(), HasSubstr("500 ms"));
  }
  model_.setStatus(3);
  EXPECT_EQ(dev.status(), 3);
}

TEST_F(Usb1408fsTest, StaleReportsAreSkipped) {
  auto& dev = open();
  model_.queueReply({0x44, 0x07, 0x00});  // left over from a timed-out GET_STATUS
  model_.queueReply({0x03, 0x01, 0x02});
  const Channel ch = diff(3, Range::kBip2_5V);
  EXPECT_NEAR(dev.readVolts(ch), testVolts(ch, 0), lsb(ch));
}

TEST_F(Usb1408fsTest, OnlyStaleReportsIsAProtocolError) {
  Usb1408fs::Options options;
  options.max_stale_replies = 2;
  Usb1408fs dev(FakeTransport::opener(model_), options);
  model_.muteNextReplies(1);
  for (int i = 0; i < 3; ++i) model_.queueReply({0x21, 0, 0, 0, 0});
  try {
    dev.status();
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_THAT(e.what(), HasSubstr("none answers GET_STATUS"));
  }
}

TEST_F(Usb1408fsTest, ShortReplyIsAProtocolError) {
  auto& dev = open();
  model_.truncateNextReply(2);
  try {
    dev.readRaw(se(0));
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_THAT(e.what(), HasSubstr("short reply from the USB-1408FS to AIN (0x10): 2 bytes, "
                                    "expected 3"));
  }
}

TEST_F(Usb1408fsTest, ShortScanPacketIsAProtocolError) {
  auto& dev = open();
  Collector sink(1);
  model_.truncateNextScanPacket(40);
  dev.startScan({{se(0)}, 1000.0, 0}, sink);
  try {
    for (int i = 0; i < 10; ++i) dev.pollScan(50ms);
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_THAT(e.what(), HasSubstr("malformed scan packet from the USB-1408FS: 40 bytes"));
  }
  EXPECT_FALSE(dev.scanning());
  EXPECT_FALSE(model_.scanning());  // AIN_STOP went out
}

TEST_F(Usb1408fsTest, ScanEndpointStall) {
  auto& dev = open();
  Collector sink(1);
  model_.stallScanEndpoint();
  dev.startScan({{se(0)}, 1000.0, 0}, sink);
  try {
    for (int i = 0; i < 10; ++i) dev.pollScan(50ms);
    FAIL();
  } catch (const StallError& e) {
    EXPECT_THAT(e.what(), HasSubstr("stalled a scan-data endpoint"));
  }
}

TEST_F(Usb1408fsTest, ScanThatStopsDeliveringTimesOut) {
  auto& dev = open();
  Collector sink(1);
  dev.startScan({{se(0)}, 1000.0, 0}, sink);
  dev.pollScan(100ms);
  const std::uint8_t stop[1] = {cmd::kAInStop};
  model_.controlOut(0x21, 0x09, 0x0212, 0, stop, 1);  // the board stops behind our back
  try {
    for (int i = 0; i < 20; ++i) dev.pollScan(100ms);
    FAIL();
  } catch (const TimeoutError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scan stopped delivering data"));
  }
  EXPECT_FALSE(dev.scanning());
}

TEST_F(Usb1408fsTest, ErroneousScanConfigurationsAreRefused) {
  auto& dev = open();
  Collector sink(1);
  EXPECT_THROW(dev.startScan({{}, 1000.0, 0}, sink), ProtocolError);
  EXPECT_THROW(dev.startScan({{se(0)}, 0.1, 0}, sink), ProtocolError);
  // Only consecutive inputs of one mode, lowest first: the order no reference driver sends is
  // refused rather than guessed.
  EXPECT_THROW(dev.startScan({{diff(0, Range::kBip10V), diff(2, Range::kBip10V)}, 1000.0, 0}, sink),
               ProtocolError);
  EXPECT_THROW(dev.startScan({{diff(1, Range::kBip10V), diff(0, Range::kBip10V)}, 1000.0, 0}, sink),
               ProtocolError);
  EXPECT_THROW(dev.startScan({{diff(3, Range::kBip10V), se(0)}, 1000.0, 0}, sink), ProtocolError);
  EXPECT_TRUE(model_.commandLog().empty());  // refused before anything was sent
  EXPECT_THROW(dev.pollScan(1ms), ProtocolError);
  EXPECT_FALSE(model_.scanning());
}

TEST_F(Usb1408fsTest, NeverWritesMemory) {
  auto& dev = open();
  dev.reopen();
  dev.readMemory(0x000, 200);
  for (const auto& c : model_.commandLog()) EXPECT_NE(c.data.at(0), cmd::kMemWrite);
  EXPECT_EQ(model_.memoryWriteAttempts(), 0);
}

TEST(ErrorMessages, NameTheDeviceAndTheUdevRule) {
  EXPECT_THAT(deviceNotFoundMessage("01ABCDEF"), HasSubstr("serial number 01ABCDEF"));
  EXPECT_THAT(deviceNotFoundMessage(""), HasSubstr("lsusb -d 09db:00a1"));
  const std::string denied = permissionDeniedMessage("opening it");
  EXPECT_THAT(denied, HasSubstr("permission denied"));
  EXPECT_THAT(denied, HasSubstr("09db:00a1"));
  EXPECT_THAT(denied, HasSubstr("config/udev/60-zerocal-usb1408fs.rules"));
}

}  // namespace
}  // namespace zerocal::usb1408fs
