// A simulated Measurement Computing USB-1408FS that answers the protocol byte for byte
// (zerocal/usb1408fs/protocol.h). It knows nothing of transports: a FakeTransport drives it for
// unit tests, a umockdev ioctl handler drives it under the real libusb transport.
//
// Time is simulated: the owner calls advanceTo() and scan packets appear when the pacer says so.
// Not thread-safe; a multi-threaded owner (the umockdev handler) holds a lock around every call.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <set>
#include <vector>

#include "zerocal/usb1408fs/protocol.h"

namespace zerocal::sim {

class Usb1408fsModel {
 public:
  // Volts at the input `channel` (as the driver names it) at simulated time `time_s` seconds.
  using AnalogSource = std::function<double(const usb1408fs::Channel& channel, double time_s)>;

  enum class Result { kOk, kStall, kNoDevice };

  struct Packet {
    std::array<std::uint8_t, usb1408fs::kPacketSize> bytes{};
    std::size_t length = 0;
  };

  struct Command {
    std::uint8_t request_type = 0;
    std::uint8_t request = 0;
    std::uint16_t value = 0;
    std::uint16_t index = 0;
    std::vector<std::uint8_t> data;
  };

  // The calibration table is drawn from `seed`: slopes 0.96..1.04, intercepts -40..40 codes, so
  // a driver that ignores it is off by tens of millivolts.
  explicit Usb1408fsModel(std::uint32_t seed = 1408);

  void setAnalogSource(AnalogSource source) { source_ = std::move(source); }

  // --- The bus side --------------------------------------------------------------------------
  bool connected() const noexcept { return connected_; }
  // A control transfer from the host. Anything the firmware would not accept stalls.
  Result controlOut(std::uint8_t request_type, std::uint8_t request, std::uint16_t value,
                    std::uint16_t index, const std::uint8_t* data, std::size_t length);
  // Next report on EP 0x81, if any.
  std::optional<Packet> takeReply();
  // Next scan packet on `endpoint` (0x83..0x85), if any; kStall when a stall was injected.
  Result takeScanPacket(std::uint8_t endpoint, std::optional<Packet>& packet);
  bool scanDataWaiting(std::uint8_t endpoint) const;

  // --- Simulated time ------------------------------------------------------------------------
  void advanceTo(std::chrono::nanoseconds time);
  std::chrono::nanoseconds now() const noexcept { return now_; }
  // When the next scan packet will be complete; nullopt if no scan runs.
  std::optional<std::chrono::nanoseconds> nextPacketTime() const;

  // --- Faults and inspection -----------------------------------------------------------------
  void unplug();
  // Plugs the board back in: power-on state (no scan, queues empty), same EEPROM.
  void replug();
  void stallNextCommand(std::uint8_t code, int times = 1);
  void stallScanEndpoint() { scan_stall_ = true; }
  void muteNextReplies(int count) { mute_replies_ = count; }  // accept, but never answer
  void truncateNextReply(std::size_t length) { truncate_reply_ = length; }
  void truncateNextScanPacket(std::size_t length) { truncate_scan_ = length; }
  void queueReply(std::vector<std::uint8_t> bytes);  // a stale report on EP 0x81
  void dropScanPackets(std::uint16_t first_index, std::uint16_t count);

  const std::vector<Command>& commandLog() const noexcept { return log_; }
  void clearCommandLog() { log_.clear(); }
  int blinkCount() const noexcept { return blinks_; }
  int memoryWriteAttempts() const noexcept { return memory_writes_; }
  int resets() const noexcept { return resets_; }
  bool scanning() const noexcept { return scan_.running; }
  std::uint64_t scanPacketsSent() const noexcept { return scan_.packets_sent; }
  std::uint64_t scanPacketsDropped() const noexcept { return scan_.packets_dropped; }
  std::uint8_t digitalOutput(int port) const { return dout_[port & 1]; }
  void setDigitalInputs(std::uint8_t port_a, std::uint8_t port_b) { din_ = {port_a, port_b}; }
  void setStatus(std::uint16_t status) { status_ = status; }
  usb1408fs::Calibration calibration(const usb1408fs::Channel& channel) const;
  const std::vector<std::uint8_t>& eeprom() const noexcept { return eeprom_; }

  // The raw word the board reports for `volts` on `channel`, the inverse of the driver's
  // conversion and calibration (quantised, clipped at full scale).
  std::uint16_t wordFor(const usb1408fs::Channel& channel, double volts) const;

 private:
  struct Scan {
    bool running = false;
    std::vector<usb1408fs::Channel> channels;
    std::chrono::nanoseconds start{0};
    double period_s = 0.0;
    std::uint64_t ticks_done = 0;
    std::uint64_t samples_total = 0;  // 0: continuous
    std::uint64_t samples_made = 0;
    std::vector<std::uint16_t> pending;  // words not yet in a packet
    std::uint16_t index = 0;
    std::size_t next_endpoint = 0;
    std::uint64_t packets_sent = 0;
    std::uint64_t packets_dropped = 0;
  };

  bool execute(const std::uint8_t* data, std::size_t length);
  bool startScan(const std::uint8_t* data);
  void reply(std::vector<std::uint8_t> bytes);
  void emitPacket(bool final_packet);
  usb1408fs::Channel decode(std::uint8_t wire_channel, std::uint8_t range) const;

  AnalogSource source_;
  bool connected_ = true;
  std::chrono::nanoseconds now_{0};
  std::vector<std::uint8_t> eeprom_;
  std::deque<Packet> replies_;
  std::array<std::deque<Packet>, 3> scan_packets_;
  std::vector<std::pair<std::uint8_t, std::uint8_t>> queue_;  // wire (channel, range)
  // Range byte last set per wire channel (AIN, ALOAD_QUEUE), for scans without the queue; 0
  // (+-20 V) at power-on is assumed, not documented.
  std::array<std::uint8_t, 16> range_{};
  std::array<std::uint8_t, 2> dir_{1, 1};
  std::array<std::uint8_t, 2> dout_{0, 0};
  std::array<std::uint8_t, 2> din_{0, 0};
  std::uint16_t status_ = 0;
  Scan scan_;
  std::set<std::uint16_t> drop_;
  std::uint8_t stall_code_ = 0;
  int stall_times_ = 0;
  bool scan_stall_ = false;
  int mute_replies_ = 0;
  std::size_t truncate_reply_ = 0;
  std::size_t truncate_scan_ = 0;
  std::vector<Command> log_;
  int blinks_ = 0;
  int memory_writes_ = 0;
  int resets_ = 0;
};

}  // namespace zerocal::sim
