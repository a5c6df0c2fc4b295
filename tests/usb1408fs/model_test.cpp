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

}  // namespace
}  // namespace zerocal::sim
