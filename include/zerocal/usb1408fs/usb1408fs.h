// The USB-1408FS protocol over a UsbTransport: commands, calibrated conversions and
// hardware-paced scans. Not thread-safe: one thread owns a Usb1408fs.
//
// Every method that talks to the board throws (errors.h):
//   DisconnectedError  the board went away; connected() turns false, call reopen() once it is back
//   StallError         the board refused the request
//   TimeoutError       no reply within Options::command_timeout (or no scan data for
//                      Options::scan_data_timeout)
//   ProtocolError      a reply or packet that cannot be right (short, malformed)
//   UsbError           anything else libusb reports
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "zerocal/usb1408fs/errors.h"
#include "zerocal/usb1408fs/protocol.h"
#include "zerocal/usb1408fs/transport.h"

namespace zerocal::usb1408fs {

enum class DigitalPort : std::uint8_t { kA = 0, kB = 1 };
enum class DigitalDirection : std::uint8_t { kOutput = 0, kInput = 1 };

struct ScanConfig {
  // 1..8 consecutive inputs of one mode, lowest first (wire numbers c, c+1, ...), loaded into the
  // channel/gain queue with their ranges.
  std::vector<Channel> channels;
  double rate_hz = 1000.0;  // scans per second (each scan converts every channel once)
  std::uint32_t scans = 0;  // 0: continuous until stopScan(); else single execution
  std::size_t transfers_per_endpoint = 4;  // asynchronous transfers in flight per endpoint
};

// One data packet's worth of calibrated samples, valid only during the callback.
struct ScanBlock {
  const double* volts = nullptr;  // volts[i] belongs to channels[(first_channel + i) % n]
  std::size_t count = 0;          // <= 31
  std::size_t first_channel = 0;  // index into ScanConfig::channels
  std::uint16_t scan_index = 0;   // the board's packet counter
};

// Receives scan data on the thread that calls pollScan(). Must not throw.
class ScanConsumer {
 public:
  virtual ~ScanConsumer() = default;
  virtual void onScanData(const ScanBlock& block) noexcept = 0;
  // `lost` packets (31 samples each) never arrived before `received_index`. The channel phase of
  // the following data is already corrected for them.
  virtual void onPacketsLost(std::uint32_t lost, std::uint16_t received_index) noexcept {}
};

struct ScanStats {
  std::uint64_t packets = 0;       // received
  std::uint64_t samples = 0;       // delivered to the consumer
  std::uint64_t lost_packets = 0;  // inferred from scan-index gaps
  std::uint64_t gaps = 0;          // number of discontinuities
  std::uint64_t late_packets = 0;  // arrived after their gap had been declared; not used
};

class Usb1408fs {
 public:
  using Opener = std::function<std::unique_ptr<UsbTransport>()>;

  struct Options {
    std::chrono::milliseconds command_timeout{500};
    std::chrono::milliseconds scan_data_timeout{1000};
    int max_stale_replies = 16;  // unrelated reports skipped while waiting for a reply
  };

  // Opens through `opener` (which throws DeviceNotFoundError / PermissionError) and reads the
  // calibration table once.
  explicit Usb1408fs(Opener opener);
  Usb1408fs(Opener opener, Options options);
  ~Usb1408fs();
  Usb1408fs(const Usb1408fs&) = delete;
  Usb1408fs& operator=(const Usb1408fs&) = delete;

  // Drops the old handle, opens again and rereads the calibration. Throws as the constructor.
  void reopen();
  bool connected() const noexcept { return transport_ != nullptr; }

  // Calibration read from the board's EEPROM at open.
  Calibration calibration(const Channel& channel) const;

  // One software-paced conversion: the raw 16-bit word, and calibrated volts.
  std::uint16_t readRaw(const Channel& channel);
  double readVolts(const Channel& channel);

  // GET_STATUS; only the low 4 bits are meaningful.
  std::uint16_t status();
  void blinkLed();
  void configureDigitalPort(DigitalPort port, DigitalDirection direction);
  std::array<std::uint8_t, 2> readDigital();  // {port A, port B}
  void writeDigital(DigitalPort port, std::uint8_t value);

  // ALOAD_QUEUE with 1..8 channels. Throws ProtocolError on a bad list.
  void loadQueue(const std::vector<Channel>& channels);

  // MEM_READ of `count` bytes from `address`, split into requests of <= 62 bytes.
  std::vector<std::uint8_t> readMemory(std::uint16_t address, std::size_t count);

  // Starts a hardware-paced scan. Allocates here, never while data flows. Returns the pacer
  // actually programmed. Throws ProtocolError on a bad configuration.
  Pacer startScan(const ScanConfig& config, ScanConsumer& consumer);
  // Delivers whatever arrives within `timeout`; returns the number of packets received.
  std::size_t pollScan(std::chrono::milliseconds timeout);
  // AIN_STOP and cancellation of every transfer. Safe without a scan and after a disconnect.
  void stopScan() noexcept;
  bool scanning() const noexcept { return scanning_; }
  // A single-execution scan has delivered all of its samples.
  bool scanComplete() const noexcept { return scan_complete_; }
  const ScanStats& scanStats() const noexcept { return stats_; }

 private:
  class PacketRouter;
  enum class PendingError { kNone, kDisconnected, kStall, kTimeout, kShortPacket, kOther };

  UsbTransport& link();
  void send(const std::uint8_t* data, std::size_t length);
  std::size_t command(const std::uint8_t* data, std::size_t length, std::uint8_t* reply,
                      std::size_t reply_length);
  void readCalibration();
  void onPacket(std::uint8_t endpoint, const std::uint8_t* data, std::size_t length,
                TransferStatus status) noexcept;
  void deliver(const std::uint8_t* data, std::uint16_t index) noexcept;
  void drainReorderBuffer() noexcept;
  bool releaseOldestHeld() noexcept;
  [[noreturn]] void raisePending();
  template <typename F>
  auto guarded(F&& f) -> decltype(f());

  Opener opener_;
  Options options_;
  std::unique_ptr<UsbTransport> transport_;
  std::array<Calibration, 32> differential_cal_{};  // [channel*8 + range]
  std::array<Calibration, 8> single_ended_cal_{};

  // Scan state, sized at startScan().
  std::unique_ptr<PacketRouter> router_;
  ScanConsumer* consumer_ = nullptr;
  std::vector<Channel> scan_channels_;
  std::vector<Calibration> scan_cal_;
  std::array<double, kSamplesPerPacket> block_{};
  // Packets that overtook an earlier one, held until it arrives (one slot per transfer in flight).
  struct Held {
    std::array<std::uint8_t, kPacketSize> bytes{};
    std::uint16_t index = 0;
    bool used = false;
  };
  std::vector<Held> held_;
  bool scanning_ = false;
  bool scan_complete_ = false;
  bool single_execution_ = false;
  std::uint16_t expected_index_ = 0;
  std::size_t channel_phase_ = 0;
  std::uint64_t samples_left_ = 0;  // single execution only
  std::chrono::milliseconds silent_for_{0};
  PendingError pending_ = PendingError::kNone;
  std::size_t pending_length_ = 0;
  ScanStats stats_;
};

}  // namespace zerocal::usb1408fs
