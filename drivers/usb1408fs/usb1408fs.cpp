#include "zerocal/usb1408fs/usb1408fs.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

namespace zerocal::usb1408fs {
namespace {

constexpr std::chrono::milliseconds kStopTimeout{100};

std::string hex2(unsigned v) {
  static const char* kDigits = "0123456789abcdef";
  std::string s = "0x00";
  s[2] = kDigits[(v >> 4) & 0xF];
  s[3] = kDigits[v & 0xF];
  return s;
}

const char* commandName(std::uint8_t code) {
  switch (code) {
    case cmd::kDConfig:
      return "DCONFIG";
    case cmd::kDIn:
      return "DIN";
    case cmd::kDOut:
      return "DOUT";
    case cmd::kAIn:
      return "AIN";
    case cmd::kAInScan:
      return "AIN_SCAN";
    case cmd::kAInStop:
      return "AIN_STOP";
    case cmd::kALoadQueue:
      return "ALOAD_QUEUE";
    case cmd::kMemRead:
      return "MEM_READ";
    case cmd::kBlinkLed:
      return "BLINK_LED";
    case cmd::kGetStatus:
      return "GET_STATUS";
    default:
      return "command";
  }
}

std::string describe(std::uint8_t code) {
  return std::string(commandName(code)) + " (" + hex2(code) + ")";
}

float getF32(const std::uint8_t* p) {
  const std::uint32_t bits = getU32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

void checkChannel(const Channel& channel) {
  const int limit = channel.mode == InputMode::kSingleEnded ? 8 : 4;
  if (channel.number < 0 || channel.number >= limit) {
    throw ProtocolError(
        std::string(channel.mode == InputMode::kSingleEnded ? "single-ended" : "differential") +
        " channel " + std::to_string(channel.number) + " does not exist on the USB-1408FS (0.." +
        std::to_string(limit - 1) + ")");
  }
  if (static_cast<std::uint8_t>(channel.range) > 7) {
    throw ProtocolError("range byte " + std::to_string(static_cast<int>(channel.range)) +
                        " is not one of the USB-1408FS ranges 0..7");
  }
}

// The reference driver scans only consecutive channels, lowest first, with the queue holding
// exactly low..high; whether the firmware follows the queue or low..high is not known for other
// orders (docs/usb1408fs.md), so only scans on which both readings agree are sent.
void checkScanChannels(const std::vector<Channel>& channels) {
  for (std::size_t i = 1; i < channels.size(); ++i) {
    if (wireChannel(channels[i]) != wireChannel(channels[i - 1]) + 1) {
      throw ProtocolError(
          "a USB-1408FS scan takes consecutive inputs of one mode, lowest first (e.g. "
          "differential 0, 1, 2); input " +
          std::to_string(i + 1) + " of the scan breaks the sequence");
    }
  }
}

}  // namespace

class Usb1408fs::PacketRouter final : public StreamSink {
 public:
  explicit PacketRouter(Usb1408fs& owner) : owner_(owner) {}
  void onPacket(std::uint8_t endpoint, const std::uint8_t* data, std::size_t length,
                TransferStatus status) noexcept override {
    owner_.onPacket(endpoint, data, length, status);
  }

 private:
  Usb1408fs& owner_;
};

Usb1408fs::Usb1408fs(Opener opener) : Usb1408fs(std::move(opener), Options{}) {}

Usb1408fs::Usb1408fs(Opener opener, Options options)
    : opener_(std::move(opener)), options_(options) {
  reopen();
}

Usb1408fs::~Usb1408fs() { stopScan(); }

void Usb1408fs::reopen() {
  stopScan();
  transport_.reset();
  transport_ = opener_();
  if (!transport_) throw DeviceNotFoundError("the USB-1408FS opener returned no transport");
  readCalibration();
}

UsbTransport& Usb1408fs::link() {
  if (!transport_) {
    throw DisconnectedError(
        "the USB-1408FS is disconnected; reconnect it and reopen the link before using it");
  }
  return *transport_;
}

template <typename F>
auto Usb1408fs::guarded(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const DisconnectedError&) {
    // The handle is dead for good; keep nothing that refers to it.
    if (transport_) transport_->stopStream();
    transport_.reset();
    scanning_ = false;
    throw;
  }
}

void Usb1408fs::send(const std::uint8_t* data, std::size_t length) {
  guarded([&] {
    try {
      link().controlOut(kSetReportRequestType, kSetReportRequest,
                        static_cast<std::uint16_t>(kOutputReport | data[0]), 0, data, length,
                        options_.command_timeout);
    } catch (const StallError& e) {
      throw StallError("the USB-1408FS refused " + describe(data[0]) +
                           " (STALL); the command or its parameters are not accepted",
                       e.libusbCode());
    } catch (const TimeoutError& e) {
      throw TimeoutError("the USB-1408FS did not accept " + describe(data[0]) + " within " +
                             std::to_string(options_.command_timeout.count()) + " ms",
                         e.libusbCode());
    }
  });
}

std::size_t Usb1408fs::command(const std::uint8_t* data, std::size_t length, std::uint8_t* reply,
                               std::size_t reply_length) {
  send(data, length);
  if (reply == nullptr) return 0;
  const std::uint8_t code = data[0];
  return guarded([&]() -> std::size_t {
    std::uint8_t buffer[kPacketSize];
    // Reports left over from an earlier, timed-out exchange may be queued on 0x81: skip those
    // whose code is not ours rather than misreading them.
    for (int attempt = 0; attempt <= options_.max_stale_replies; ++attempt) {
      std::size_t n = 0;
      try {
        n = link().interruptIn(kReplyEndpoint, buffer, sizeof buffer, options_.command_timeout);
      } catch (const TimeoutError& e) {
        throw TimeoutError("no reply from the USB-1408FS to " + describe(code) + " within " +
                               std::to_string(options_.command_timeout.count()) +
                               " ms; check the USB cable and that no other program uses the board",
                           e.libusbCode());
      } catch (const StallError& e) {
        throw StallError(
            "the USB-1408FS stalled the reply endpoint while answering " + describe(code),
            e.libusbCode());
      }
      if (n == 0 || buffer[0] != code) continue;
      if (n < reply_length) {
        throw ProtocolError("short reply from the USB-1408FS to " + describe(code) + ": " +
                            std::to_string(n) + " bytes, expected " + std::to_string(reply_length));
      }
      std::memcpy(reply, buffer, reply_length);
      return n;
    }
    throw ProtocolError("the USB-1408FS sent " + std::to_string(options_.max_stale_replies + 1) +
                        " reports but none answers " + describe(code) +
                        "; is it a USB-1408FS and not a USB-1408FS-Plus?");
  });
}

std::vector<std::uint8_t> Usb1408fs::readMemory(std::uint16_t address, std::size_t count) {
  std::vector<std::uint8_t> out;
  out.reserve(count);
  while (out.size() < count) {
    const std::size_t chunk = std::min(kMaxMemReadCount, count - out.size());
    const auto at = static_cast<std::uint16_t>(address + out.size());
    std::uint8_t request[5] = {cmd::kMemRead, 0, 0, 0 /* memory type: always initialised */,
                               static_cast<std::uint8_t>(chunk)};
    putU16(request + 1, at);
    std::uint8_t reply[1 + kMaxMemReadCount];
    command(request, sizeof request, reply, 1 + chunk);
    out.insert(out.end(), reply + 1, reply + 1 + chunk);
  }
  return out;
}

void Usb1408fs::readCalibration() {
  const std::vector<std::uint8_t> table =
      readMemory(kCalDifferentialBase, kCalTableEnd - kCalDifferentialBase);
  auto decode = [&](std::uint16_t address, const char* what) {
    const std::uint8_t* p = table.data() + (address - kCalDifferentialBase);
    Calibration cal{getF32(p), getF32(p + 4)};
    // An erased (0xFF) or zeroed EEPROM gives NaN or a zero slope; a board in that state would
    // read garbage, so say so rather than scale by nonsense.
    if (!std::isfinite(cal.slope) || !std::isfinite(cal.intercept) || cal.slope < 0.5 ||
        cal.slope > 1.5) {
      throw ProtocolError(std::string("the USB-1408FS calibration table is unusable at ") + what +
                          " (slope " + std::to_string(cal.slope) + ", intercept " +
                          std::to_string(cal.intercept) +
                          "); the board needs recalibration with MCC's InstaCal");
    }
    return cal;
  };
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 8; ++r) {
      Channel ch{c, InputMode::kDifferential, static_cast<Range>(r)};
      differential_cal_[c * 8 + r] = decode(calibrationAddress(ch), "a differential entry");
    }
  }
  for (int c = 0; c < 8; ++c) {
    Channel ch{c, InputMode::kSingleEnded, Range::kBip10V};
    single_ended_cal_[c] = decode(calibrationAddress(ch), "a single-ended entry");
  }
}

Calibration Usb1408fs::calibration(const Channel& channel) const {
  checkChannel(channel);
  if (channel.mode == InputMode::kSingleEnded) return single_ended_cal_[channel.number];
  return differential_cal_[channel.number * 8 + static_cast<int>(channel.range)];
}

std::uint16_t Usb1408fs::readRaw(const Channel& channel) {
  checkChannel(channel);
  const std::uint8_t request[3] = {cmd::kAIn, wireChannel(channel), wireRange(channel)};
  std::uint8_t reply[3];
  command(request, sizeof request, reply, sizeof reply);
  return getU16(reply + 1);
}

double Usb1408fs::readVolts(const Channel& channel) {
  const std::uint16_t word = readRaw(channel);
  const Calibration cal = calibration(channel);
  return codeToVolts(rawCode(channel, word) * cal.slope + cal.intercept, channel);
}

std::uint16_t Usb1408fs::status() {
  // The full 3-byte report, as the C driver that runs on boards sends it (docs/usb1408fs.md).
  const std::uint8_t request[3] = {cmd::kGetStatus, 0, 0};
  std::uint8_t reply[3];
  command(request, sizeof request, reply, sizeof reply);
  return getU16(reply + 1);
}

void Usb1408fs::blinkLed() {
  const std::uint8_t request[1] = {cmd::kBlinkLed};
  command(request, sizeof request, nullptr, 0);
}

void Usb1408fs::configureDigitalPort(DigitalPort port, DigitalDirection direction) {
  const std::uint8_t request[3] = {cmd::kDConfig, static_cast<std::uint8_t>(port),
                                   static_cast<std::uint8_t>(direction)};
  command(request, sizeof request, nullptr, 0);
}

std::array<std::uint8_t, 2> Usb1408fs::readDigital() {
  const std::uint8_t request[1] = {cmd::kDIn};
  std::uint8_t reply[3];
  command(request, sizeof request, reply, sizeof reply);
  return {reply[1], reply[2]};
}

void Usb1408fs::writeDigital(DigitalPort port, std::uint8_t value) {
  const std::uint8_t request[3] = {cmd::kDOut, static_cast<std::uint8_t>(port), value};
  command(request, sizeof request, nullptr, 0);
}

void Usb1408fs::loadQueue(const std::vector<Channel>& channels) {
  if (channels.empty() || channels.size() > kMaxQueueLength) {
    throw ProtocolError("the USB-1408FS channel queue takes 1..8 channels, got " +
                        std::to_string(channels.size()));
  }
  std::uint8_t request[2 + 2 * kMaxQueueLength] = {cmd::kALoadQueue,
                                                   static_cast<std::uint8_t>(channels.size())};
  for (std::size_t i = 0; i < channels.size(); ++i) {
    checkChannel(channels[i]);
    request[2 + 2 * i] = wireChannel(channels[i]);
    request[3 + 2 * i] = wireRange(channels[i]);
  }
  command(request, sizeof request, nullptr, 0);
}

Pacer Usb1408fs::startScan(const ScanConfig& config, ScanConsumer& consumer) {
  if (scanning_) throw ProtocolError("a scan is already running; stop it first");
  if (config.transfers_per_endpoint == 0) {
    throw ProtocolError("a scan needs at least one transfer in flight per endpoint");
  }
  checkScanChannels(config.channels);
  const Pacer pacer = computePacer(config.rate_hz);
  const std::size_t n = config.channels.size();
  const std::uint64_t total_samples = static_cast<std::uint64_t>(config.scans) * n;
  if (total_samples > 0xFFFFFFFFull) {
    throw ProtocolError("a single-execution scan is limited to 2^32-1 samples");
  }
  loadQueue(config.channels);

  scan_channels_ = config.channels;
  scan_cal_.clear();
  for (const Channel& ch : scan_channels_) scan_cal_.push_back(calibration(ch));
  consumer_ = &consumer;
  stats_ = ScanStats{};
  expected_index_ = 0;
  channel_phase_ = 0;
  samples_left_ = total_samples;
  single_execution_ = config.scans > 0;
  scan_complete_ = false;
  silent_for_ = std::chrono::milliseconds{0};
  pending_ = PendingError::kNone;
  if (!router_) router_ = std::make_unique<PacketRouter>(*this);
  held_.assign(kScanEndpoints.size() * config.transfers_per_endpoint, Held{});

  // Transfers go in before the command so that no early packet finds the endpoints unserviced.
  guarded([&] {
    link().startStream(kScanEndpoints.data(), kScanEndpoints.size(), config.transfers_per_endpoint,
                       kPacketSize, *router_);
  });
  scanning_ = true;

  // Low and high are the first and last channel numbers, as the reference driver sends them with
  // the queue; count is in conversions (scans x channels), which is also how the single-execution
  // end is recognised here (docs/usb1408fs.md: evidence and what is inferred).
  std::uint8_t request[11] = {cmd::kAInScan, wireChannel(config.channels.front()),
                              wireChannel(config.channels.back())};
  putU32(request + 3, static_cast<std::uint32_t>(total_samples));
  request[7] = pacer.prescale;
  putU16(request + 8, pacer.preload);
  request[10] =
      static_cast<std::uint8_t>(kScanUseQueue | (config.scans > 0 ? kScanSingleExecution : 0));
  try {
    command(request, sizeof request, nullptr, 0);
  } catch (...) {
    stopScan();
    throw;
  }
  return pacer;
}

void Usb1408fs::onPacket(std::uint8_t endpoint, const std::uint8_t* data, std::size_t length,
                         TransferStatus status) noexcept {
  if (!scanning_ || pending_ != PendingError::kNone) return;
  switch (status) {
    case TransferStatus::kCompleted:
      break;
    case TransferStatus::kCancelled:
      return;
    case TransferStatus::kNoDevice:
      pending_ = PendingError::kDisconnected;
      return;
    case TransferStatus::kStall:
      pending_ = PendingError::kStall;
      return;
    case TransferStatus::kTimedOut:
      pending_ = PendingError::kTimeout;
      return;
    default:
      pending_ = PendingError::kOther;
      return;
  }
  if (scan_complete_) return;  // padding packets after the last sample
  if (length < kPacketSize) {
    pending_ = PendingError::kShortPacket;
    pending_length_ = length;
    return;
  }
  ++stats_.packets;
  const std::uint16_t index = getU16(data + kScanIndexOffset);
  const auto ahead = static_cast<std::uint16_t>(index - expected_index_);
  if (ahead == 0) {
    deliver(data, index);
    drainReorderBuffer();
    return;
  }
  if (ahead >= 0x8000) {
    // Behind: a packet already given up as lost turned up after all. Too late to use.
    ++stats_.late_packets;
    return;
  }
  // Ahead: the endpoints complete independently, so a later packet may overtake an earlier one
  // on another endpoint. Hold it until the gap fills or the buffer (as deep as the transfers in
  // flight) overflows; only then is the gap real.
  for (;;) {
    for (Held& h : held_) {
      if (!h.used) {
        std::memcpy(h.bytes.data(), data, kPacketSize);
        h.index = index;
        h.used = true;
        return;
      }
    }
    releaseOldestHeld();
    const auto now_ahead = static_cast<std::uint16_t>(index - expected_index_);
    if (now_ahead == 0) {
      deliver(data, index);
      drainReorderBuffer();
      return;
    }
    if (now_ahead >= 0x8000) {
      ++stats_.late_packets;
      return;
    }
  }
}

void Usb1408fs::drainReorderBuffer() noexcept {
  for (bool found = true; found && !scan_complete_;) {
    found = false;
    for (Held& h : held_) {
      if (h.used && h.index == expected_index_) {
        h.used = false;
        deliver(h.bytes.data(), h.index);
        found = true;
      }
    }
  }
  if (scan_complete_) {
    for (Held& h : held_) h.used = false;
  }
}

bool Usb1408fs::releaseOldestHeld() noexcept {
  Held* oldest = nullptr;
  for (Held& h : held_) {
    if (h.used &&
        (oldest == nullptr || static_cast<std::uint16_t>(h.index - expected_index_) <
                                  static_cast<std::uint16_t>(oldest->index - expected_index_))) {
      oldest = &h;
    }
  }
  if (oldest == nullptr) return false;
  oldest->used = false;
  deliver(oldest->bytes.data(), oldest->index);  // records the gap before it
  drainReorderBuffer();
  return true;
}

void Usb1408fs::deliver(const std::uint8_t* data, std::uint16_t index) noexcept {
  const std::size_t n = scan_channels_.size();
  const auto lost = static_cast<std::uint16_t>(index - expected_index_);
  if (lost != 0) {
    // Keep the channel assignment right across the hole: each lost packet held 31 samples.
    ++stats_.gaps;
    stats_.lost_packets += lost;
    channel_phase_ = (channel_phase_ + static_cast<std::size_t>(lost) * kSamplesPerPacket) % n;
    if (single_execution_) {
      const std::uint64_t skipped = static_cast<std::uint64_t>(lost) * kSamplesPerPacket;
      samples_left_ = skipped >= samples_left_ ? 0 : samples_left_ - skipped;
    }
    consumer_->onPacketsLost(lost, index);
  }
  expected_index_ = static_cast<std::uint16_t>(index + 1);

  std::size_t count = kSamplesPerPacket;
  const bool single = single_execution_;
  if (single && samples_left_ < count) count = static_cast<std::size_t>(samples_left_);
  const std::size_t first = channel_phase_;
  for (std::size_t i = 0; i < count; ++i) {
    const Channel& ch = scan_channels_[channel_phase_];
    const Calibration& cal = scan_cal_[channel_phase_];
    const int code = rawCode(ch, getU16(data + 2 * i));
    block_[i] = codeToVolts(code * cal.slope + cal.intercept, ch);
    if (++channel_phase_ == n) channel_phase_ = 0;
  }
  if (single) {
    samples_left_ -= count;
  }
  if (single && samples_left_ == 0) {
    scan_complete_ = true;
  }
  stats_.samples += count;
  if (count > 0) {
    ScanBlock block;
    block.volts = block_.data();
    block.count = count;
    block.first_channel = first;
    block.scan_index = index;
    consumer_->onScanData(block);
  }
}

std::size_t Usb1408fs::pollScan(std::chrono::milliseconds timeout) {
  if (!scanning_) throw ProtocolError("pollScan() without a running scan");
  const std::uint64_t before = stats_.packets;
  guarded([&] { link().pollStream(timeout); });
  if (pending_ != PendingError::kNone) raisePending();
  const auto received = static_cast<std::size_t>(stats_.packets - before);
  if (received == 0) {
    // Nothing more is coming to fill a hole: the held packets are as good as they will get.
    while (releaseOldestHeld()) {
    }
  }
  if (received > 0 || scan_complete_) {
    silent_for_ = std::chrono::milliseconds{0};
  } else {
    silent_for_ += timeout;
    if (silent_for_ >= options_.scan_data_timeout) {
      const auto waited = silent_for_.count();
      stopScan();
      throw TimeoutError("the USB-1408FS scan stopped delivering data: nothing for " +
                         std::to_string(waited) + " ms after " + std::to_string(stats_.packets) +
                         " packets");
    }
  }
  return received;
}

void Usb1408fs::raisePending() {
  const PendingError what = pending_;
  const std::uint64_t packets = stats_.packets;
  const std::string after = " after " + std::to_string(packets) + " packets";
  pending_ = PendingError::kNone;
  if (what == PendingError::kDisconnected) {
    if (transport_) transport_->stopStream();
    transport_.reset();
    scanning_ = false;
    throw DisconnectedError("the USB-1408FS was unplugged during the scan" + after +
                            " (LIBUSB_ERROR_NO_DEVICE); reconnect it, then reopen the link");
  }
  stopScan();
  switch (what) {
    case PendingError::kStall:
      throw StallError("the USB-1408FS stalled a scan-data endpoint" + after);
    case PendingError::kTimeout:
      throw TimeoutError("a USB-1408FS scan transfer timed out" + after);
    case PendingError::kShortPacket:
      throw ProtocolError("malformed scan packet from the USB-1408FS: " +
                          std::to_string(pending_length_) + " bytes, expected 64" + after);
    default:
      throw UsbError("a USB-1408FS scan transfer failed" + after);
  }
}

void Usb1408fs::stopScan() noexcept {
  if (!scanning_) return;
  scanning_ = false;
  if (!transport_) return;
  // Best effort: after an unplug or a stall the stop command may fail, and the transfers must be
  // reclaimed regardless.
  try {
    const std::uint8_t request[1] = {cmd::kAInStop};
    transport_->controlOut(kSetReportRequestType, kSetReportRequest,
                           static_cast<std::uint16_t>(kOutputReport | cmd::kAInStop), 0, request,
                           sizeof request, kStopTimeout);
  } catch (const DisconnectedError&) {
    transport_->stopStream();
    transport_.reset();
    return;
  } catch (const Error&) {
  }
  transport_->stopStream();
}

}  // namespace zerocal::usb1408fs
