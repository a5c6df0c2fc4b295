// The simulated board on its own: it must refuse what the firmware refuses, so that the driver
// tests mean something.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "zerocal/sim/usb1408fs_model.h"

namespace zerocal::sim {
namespace {

using usb1408fs::Channel;
using usb1408fs::InputMode;
using usb1408fs::Range;
using Result = Usb1408fsModel::Result;

Result send(Usb1408fsModel& m, std::vector<std::uint8_t> d) {
  return m.controlOut(0x21, 0x09, static_cast<std::uint16_t>(0x0200 | d[0]), 0, d.data(), d.size());
}

TEST(Usb1408fsModel, StallsMalformedCommands) {
  Usb1408fsModel m;
  EXPECT_EQ(send(m, {0x10, 0, 0, 0}), Result::kStall);      // AIN with padding
  EXPECT_EQ(send(m, {0x10, 9, 3}), Result::kStall);         // single-ended with a range
  EXPECT_EQ(send(m, {0x30, 0, 2, 0, 63}), Result::kStall);  // MEM_READ over 62
  EXPECT_EQ(send(m, {0x30, 0, 2, 7, 8}), Result::kStall);   // uninitialised memory type
  EXPECT_EQ(send(m, {0x31, 0, 2, 1, 0}), Result::kStall);   // MEM_WRITE is never allowed
  EXPECT_EQ(m.memoryWriteAttempts(), 1);
  EXPECT_EQ(send(m, {0x7F}), Result::kStall);
  const std::uint8_t ain[3] = {0x10, 0, 0};
  EXPECT_EQ(m.controlOut(0x21, 0x09, 0x0211, 0, ain, 3), Result::kStall);  // wValue mismatch
  EXPECT_EQ(send(m, {0x10, 0, 0}), Result::kOk);
  EXPECT_TRUE(m.takeReply().has_value());
}

TEST(Usb1408fsModel, WordsInvertTheCalibratedConversion) {
  Usb1408fsModel m;
  const Channel d{1, InputMode::kDifferential, Range::kBip20V};
  const auto cal = m.calibration(d);
  EXPECT_NE(cal.slope, 1.0f);
  EXPECT_NE(cal.intercept, 0.0f);
  EXPECT_EQ(m.wordFor(d, 100.0), 0x7FFC);  // clipped
  EXPECT_EQ(m.wordFor(d, -100.0), 0x8000);
  const Channel s{0, InputMode::kSingleEnded, Range::kBip10V};
  EXPECT_EQ(m.wordFor(s, 100.0), 0x7FFA);
  EXPECT_EQ(m.wordFor(s, -100.0), 0x0000);
}

TEST(Usb1408fsModel, ScanPacketsRoundRobinWithIndexOnTheSimulatedClock) {
  Usb1408fsModel m;
  ASSERT_EQ(send(m, {0x13, 1, 8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}), Result::kOk);
  // 1000 scans/s of one channel: a packet every 31 ms.
  ASSERT_EQ(send(m, {0x11, 0, 0, 0, 0, 0, 0, 0, 0x10, 0x27, 0x10}), Result::kOk);
  EXPECT_EQ(m.nextPacketTime(), std::chrono::milliseconds(31));
  m.advanceTo(std::chrono::milliseconds(94));
  std::optional<Usb1408fsModel::Packet> p;
  for (std::uint8_t k = 0; k < 3; ++k) {
    ASSERT_EQ(m.takeScanPacket(static_cast<std::uint8_t>(0x83 + k), p), Result::kOk);
    ASSERT_TRUE(p.has_value());
    EXPECT_EQ(p->bytes[62] | (p->bytes[63] << 8), k);
  }
  m.unplug();
  EXPECT_EQ(m.takeScanPacket(0x83, p), Result::kNoDevice);
  EXPECT_EQ(send(m, {0x40}), Result::kNoDevice);
}

// What the reference C driver (wjasper/Linux_Drivers, usb-1408FS.c), which runs on boards, sends.
TEST(Usb1408fsModel, AcceptsTheReferenceDriversGetStatusOfThreeBytes) {
  Usb1408fsModel m;
  m.setStatus(0x0009);
  ASSERT_EQ(send(m, {0x44, 0, 0}), Result::kOk);
  const auto r = m.takeReply();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->length, 3u);
  EXPECT_EQ(r->bytes[0], 0x44);
  EXPECT_EQ(r->bytes[1] | (r->bytes[2] << 8), 0x0009);
  ASSERT_EQ(send(m, {0x44}), Result::kOk);  // the Python driver's single byte
  EXPECT_TRUE(m.takeReply().has_value());
  EXPECT_EQ(send(m, {0x44, 0}), Result::kStall);
}

// First 31 samples of a single-channel scan, as the driver would read them.
std::vector<std::uint16_t> firstPacket(Usb1408fsModel& m) {
  m.advanceTo(m.now() + std::chrono::milliseconds(40));
  std::optional<Usb1408fsModel::Packet> p;
  EXPECT_EQ(m.takeScanPacket(0x83, p), Result::kOk);
  std::vector<std::uint16_t> words;
  if (p)
    for (int i = 0; i < 31; ++i) words.push_back(p->bytes[2 * i] | (p->bytes[2 * i + 1] << 8));
  return words;
}

TEST(Usb1408fsModel, QueuedScanTakesChannelNumbersAsTheReferenceDriverSendsThem) {
  Usb1408fsModel m;
  m.setAnalogSource([](const Channel& ch, double) { return ch.number == 2 ? 3.0 : -1.0; });
  // usbAInScan_USB1408FS_SE for single-ended 2 only: the queue holds wire channel 10, and
  // low = high = 10 (a channel number, not queue position 0).
  ASSERT_EQ(send(m, {0x13, 1, 10, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}), Result::kOk);
  EXPECT_EQ(send(m, {0x11, 10, 16, 62, 0, 0, 0, 0, 0x10, 0x27, 0x11}), Result::kStall);  // no 16
  ASSERT_EQ(send(m, {0x11, 10, 10, 62, 0, 0, 0, 0, 0x10, 0x27, 0x11}), Result::kOk);
  const Channel se2{2, InputMode::kSingleEnded, Range::kBip10V};
  const auto words = firstPacket(m);
  ASSERT_EQ(words.size(), 31u);
  for (std::uint16_t w : words) EXPECT_EQ(w, m.wordFor(se2, 3.0));
}

TEST(Usb1408fsModel, ScanWithoutTheQueueUsesEachChannelsLastSetRange) {
  Usb1408fsModel m;
  m.setAnalogSource([](const Channel&, double) { return 0.7; });
  ASSERT_EQ(send(m, {0x10, 1, 7}), Result::kOk);  // AIN of differential 1 at +-1 V
  ASSERT_TRUE(m.takeReply().has_value());
  ASSERT_EQ(send(m, {0x11, 1, 1, 31, 0, 0, 0, 0, 0x10, 0x27, 0x01}), Result::kOk);
  const Channel at_1v{1, InputMode::kDifferential, Range::kBip1V};
  const auto words = firstPacket(m);
  ASSERT_EQ(words.size(), 31u);
  EXPECT_EQ(words.front(), m.wordFor(at_1v, 0.7));
  EXPECT_NE(words.front(), m.wordFor({1, InputMode::kDifferential, Range::kBip20V}, 0.7));
}

}  // namespace
}  // namespace zerocal::sim
