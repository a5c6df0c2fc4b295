// Wire facts of the Measurement Computing USB-1408FS (not the -Plus) and the pure conversions,
// shared by the driver and the simulated board (after W. Jasper's drivers and MCC's guide).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace zerocal::usb1408fs {

inline constexpr std::uint16_t kVendorId = 0x09DB;
inline constexpr std::uint16_t kProductId = 0x00A1;
inline constexpr int kInterfaceCount = 4;

inline constexpr std::uint8_t kReplyEndpoint = 0x81;
inline constexpr std::array<std::uint8_t, 3> kScanEndpoints = {0x83, 0x84, 0x85};
inline constexpr std::size_t kPacketSize = 64;
inline constexpr std::size_t kSamplesPerPacket = 31;
inline constexpr std::size_t kScanIndexOffset = 62;

// HID SET_REPORT: class request to an interface, host to device.
inline constexpr std::uint8_t kSetReportRequestType = 0x21;
inline constexpr std::uint8_t kSetReportRequest = 0x09;
inline constexpr std::uint16_t kOutputReport = 0x0200;

namespace cmd {
inline constexpr std::uint8_t kDConfig = 0x01;
inline constexpr std::uint8_t kDIn = 0x03;
inline constexpr std::uint8_t kDOut = 0x04;
inline constexpr std::uint8_t kAIn = 0x10;
inline constexpr std::uint8_t kAInScan = 0x11;
inline constexpr std::uint8_t kAInStop = 0x12;
inline constexpr std::uint8_t kALoadQueue = 0x13;
inline constexpr std::uint8_t kMemRead = 0x30;
inline constexpr std::uint8_t kMemWrite = 0x31;
inline constexpr std::uint8_t kBlinkLed = 0x40;
inline constexpr std::uint8_t kReset = 0x41;
inline constexpr std::uint8_t kGetStatus = 0x44;
}  // namespace cmd

// AIN_SCAN option bits.
inline constexpr std::uint8_t kScanSingleExecution = 0x01;
inline constexpr std::uint8_t kScanImmediateTransfer = 0x02;
inline constexpr std::uint8_t kScanExternalTrigger = 0x04;
inline constexpr std::uint8_t kScanUseQueue = 0x10;

inline constexpr std::size_t kMaxQueueLength = 8;
inline constexpr std::size_t kMaxMemReadCount = 62;

// Calibration table in EEPROM: little-endian float32 (slope, intercept) per differential
// (channel, range) at kCalDifferentialBase + (c*8 + r)*8, per single-ended channel at
// kCalSingleEndedBase + c*8.
inline constexpr std::uint16_t kCalDifferentialBase = 0x200;
inline constexpr std::uint16_t kCalSingleEndedBase = 0x300;
inline constexpr std::uint16_t kCalTableEnd = 0x340;  // one past 0x33F

inline constexpr double kPacerClockHz = 10e6;

enum class InputMode { kDifferential, kSingleEnded };

// Range byte on the wire. Single-ended inputs are always +-10 V and send range 0.
enum class Range : std::uint8_t {
  kBip20V = 0,
  kBip10V = 1,
  kBip5V = 2,
  kBip4V = 3,
  kBip2_5V = 4,
  kBip2V = 5,
  kBip1_25V = 6,
  kBip1V = 7,
};

// One analog input as the user names it. Differential channels 0..3, single-ended 0..7.
struct Channel {
  int number = 0;
  InputMode mode = InputMode::kDifferential;
  Range range = Range::kBip10V;  // ignored (+-10 V) for single-ended
};

// Full-scale volts of a range (+-full_scale).
double fullScaleVolts(Range range);
double fullScaleVolts(const Channel& channel);

// Channel number as sent on the wire (single-ended c is c + 8) and the range byte sent with it.
std::uint8_t wireChannel(const Channel& channel);
std::uint8_t wireRange(const Channel& channel);

// Whether two channels use a common screw terminal. Differential pair n is wired to the terminals
// of single-ended inputs n (CHn IN HI) and n + 4 (CHn IN LO): the USB-1208FS/1408FS pinout.
bool sharesTerminal(const Channel& a, const Channel& b);

// Raw 16-bit word -> signed ADC code, exactly as the firmware notes: differential 14-bit
// (-8192..8191), single-ended 13-bit effective with the firmware's end-of-range quirks.
int differentialCode(std::uint16_t word);
int singleEndedCode(std::uint16_t word);
int rawCode(const Channel& channel, std::uint16_t word);

// Corrected code (after calibration, floating point) -> volts.
double codeToVolts(double code, const Channel& channel);

// EEPROM address of the channel's (slope, intercept) pair.
std::uint16_t calibrationAddress(const Channel& channel);

struct Calibration {
  double slope = 1.0;
  double intercept = 0.0;
};

// Pacer settings for a requested scan rate (scans per second, i.e. per-channel rate: one pacer
// tick starts a conversion of every channel in the scan list). The smallest prescale 0..8 whose
// preload fits 16 bits. Throws zerocal::usb1408fs::ProtocolError if the rate is not positive or
// below what prescale 8 can reach.
struct Pacer {
  std::uint8_t prescale = 0;
  std::uint16_t preload = 0;
  double actual_rate_hz = 0.0;
};
Pacer computePacer(double rate_hz);

// Little-endian helpers.
inline std::uint16_t getU16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
inline void putU16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v & 0xFF);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
inline std::uint32_t getU32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}
inline void putU32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

}  // namespace zerocal::usb1408fs
