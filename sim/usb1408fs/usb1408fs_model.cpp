#include "zerocal/sim/usb1408fs_model.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

namespace zerocal::sim {

using namespace zerocal::usb1408fs;

namespace {

// The board's FIFO is finite: beyond this many unread packets per endpoint, new data is lost,
// as on a host that stops servicing the endpoints.
constexpr std::size_t kMaxQueuedPackets = 512;

void putF32(std::uint8_t* p, float f) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  putU32(p, bits);
}

float getF32(const std::uint8_t* p) {
  const std::uint32_t bits = getU32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

}  // namespace

Usb1408fsModel::Usb1408fsModel(std::uint32_t seed) : eeprom_(0x400, 0xFF) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> slope(0.96f, 1.04f);
  std::uniform_real_distribution<float> intercept(-40.0f, 40.0f);
  for (std::uint16_t a = kCalDifferentialBase; a < kCalTableEnd; a += 8) {
    putF32(&eeprom_[a], slope(rng));
    putF32(&eeprom_[a + 4], intercept(rng));
  }
}

Calibration Usb1408fsModel::calibration(const Channel& channel) const {
  const std::uint16_t a = calibrationAddress(channel);
  return {getF32(&eeprom_[a]), getF32(&eeprom_[a + 4])};
}

std::uint16_t Usb1408fsModel::wordFor(const Channel& channel, double volts) const {
  const Calibration cal = calibration(channel);
  const double ideal = volts * 8191.0 / fullScaleVolts(channel);
  // The driver computes code * slope + intercept, so the board reports the pre-image.
  const double raw = std::round((ideal - cal.intercept) / cal.slope);
  const int code = static_cast<int>(std::clamp(raw, -8192.0, 8191.0));
  if (channel.mode == InputMode::kDifferential) {
    return static_cast<std::uint16_t>(static_cast<std::int16_t>(code * 4));
  }
  const int u = code + 0x2000;
  if (u > 0x3ffc) return 0x7ffa;  // the firmware's "top of range" pattern
  return static_cast<std::uint16_t>(u << 1);
}

Channel Usb1408fsModel::decode(std::uint8_t wire_channel, std::uint8_t range) const {
  if (wire_channel >= 8) return {wire_channel - 8, InputMode::kSingleEnded, Range::kBip10V};
  return {wire_channel, InputMode::kDifferential, static_cast<Range>(range)};
}

Usb1408fsModel::Result Usb1408fsModel::controlOut(std::uint8_t request_type, std::uint8_t request,
                                                  std::uint16_t value, std::uint16_t index,
                                                  const std::uint8_t* data, std::size_t length) {
  if (!connected_) return Result::kNoDevice;
  log_.push_back(
      {request_type, request, value, index, std::vector<std::uint8_t>(data, data + length)});
  if (request_type != kSetReportRequestType || request != kSetReportRequest || index != 0 ||
      length == 0 || value != (kOutputReport | data[0])) {
    return Result::kStall;
  }
  if (stall_times_ > 0 && data[0] == stall_code_) {
    --stall_times_;
    return Result::kStall;
  }
  return execute(data, length) ? Result::kOk : Result::kStall;
}

void Usb1408fsModel::reply(std::vector<std::uint8_t> bytes) {
  if (mute_replies_ > 0) {
    --mute_replies_;
    return;
  }
  if (truncate_reply_ > 0) {
    bytes.resize(std::min(bytes.size(), truncate_reply_));
    truncate_reply_ = 0;
  }
  queueReply(std::move(bytes));
}

void Usb1408fsModel::queueReply(std::vector<std::uint8_t> bytes) {
  Packet p;
  p.length = std::min(bytes.size(), p.bytes.size());
  std::copy_n(bytes.begin(), p.length, p.bytes.begin());
  replies_.push_back(p);
}

bool Usb1408fsModel::execute(const std::uint8_t* d, std::size_t n) {
  switch (d[0]) {
    case cmd::kDConfig:
      if (n != 3 || d[1] > 1 || d[2] > 1) return false;
      dir_[d[1]] = d[2];
      return true;
    case cmd::kDIn:
      if (n != 1 && n != 2) return false;
      reply({cmd::kDIn, static_cast<std::uint8_t>(dir_[0] ? din_[0] : dout_[0]),
             static_cast<std::uint8_t>(dir_[1] ? din_[1] : dout_[1])});
      return true;
    case cmd::kDOut:
      if (n != 3 || d[1] > 1 || dir_[d[1]] != 0) return false;
      dout_[d[1]] = d[2];
      return true;
    case cmd::kAIn: {
      if (n != 3 || d[1] > 15 || d[2] > 7 || (d[1] >= 8 && d[2] != 0)) return false;
      range_[d[1]] = d[2];
      const Channel ch = decode(d[1], d[2]);
      const double volts = source_ ? source_(ch, now_.count() * 1e-9) : 0.0;
      std::vector<std::uint8_t> r(3);
      r[0] = cmd::kAIn;
      putU16(&r[1], wordFor(ch, volts));
      reply(std::move(r));
      return true;
    }
    case cmd::kAInScan:
      return n == 11 && startScan(d);
    case cmd::kAInStop:
      if (n != 1) return false;
      scan_.running = false;
      return true;
    case cmd::kALoadQueue: {
      if (n != 2 + 2 * kMaxQueueLength || d[1] == 0 || d[1] > kMaxQueueLength) return false;
      queue_.clear();
      for (std::size_t i = 0; i < d[1]; ++i) {
        const std::uint8_t ch = d[2 + 2 * i], range = d[3 + 2 * i];
        if (ch > 15 || range > 7 || (ch >= 8 && range != 0)) return false;
        queue_.emplace_back(ch, range);
      }
      for (const auto& [ch, range] : queue_) range_[ch] = range;
      return true;
    }
    case cmd::kMemRead: {
      if (n != 5 || d[3] != 0 || d[4] == 0 || d[4] > kMaxMemReadCount) return false;
      const std::size_t address = getU16(d + 1), count = d[4];
      if (address + count > eeprom_.size()) return false;
      std::vector<std::uint8_t> r(1 + count);
      r[0] = cmd::kMemRead;
      std::copy_n(eeprom_.begin() + address, count, r.begin() + 1);
      reply(std::move(r));
      return true;
    }
    case cmd::kMemWrite:
      // Calibration memory needs an unlock this model never grants: the driver must not write.
      ++memory_writes_;
      return false;
    case cmd::kBlinkLed:
      if (n != 1) return false;
      ++blinks_;
      return true;
    case cmd::kReset:
      if (n != 1) return false;
      ++resets_;
      unplug();  // it drops off the bus and re-enumerates
      return true;
    case cmd::kGetStatus: {
      // The C driver that runs on boards sends the report's full 3 bytes, the Python one 1.
      if (n != 1 && n != 3) return false;
      std::vector<std::uint8_t> r(3);
      r[0] = cmd::kGetStatus;
      putU16(&r[1], status_);
      reply(std::move(r));
      return true;
    }
    default:
      return false;
  }
}

bool Usb1408fsModel::startScan(const std::uint8_t* d) {
  if (scan_.running) return false;
  const std::uint8_t low = d[1], high = d[2];
  const std::uint32_t count = getU32(d + 3);
  const std::uint8_t prescale = d[7];
  const std::uint16_t preload = getU16(d + 8);
  const std::uint8_t options = d[10];
  if (prescale > 8 || preload == 0 || high < low) return false;
  Scan scan;
  // Low and high are channel numbers (0..7 differential, 8..15 single-ended), also with the queue:
  // the reference driver loads the queue with single-ended 0..n-1 and scans "8..8+n-1"
  // (docs/usb1408fs.md). With the queue the board converts the queue in order; without it,
  // channels low..high, each at the range last set for it by AIN or ALOAD_QUEUE.
  if (high > 15) return false;
  if (options & kScanUseQueue) {
    if (queue_.empty()) return false;
    for (const auto& [ch, range] : queue_) scan.channels.push_back(decode(ch, range));
  } else {
    if (low < 8 && high >= 8) return false;
    for (std::size_t c = low; c <= high; ++c)
      scan.channels.push_back(decode(static_cast<std::uint8_t>(c), range_[c]));
  }
  if ((options & kScanSingleExecution) && count == 0) return false;
  scan.running = true;
  scan.start = now_;
  scan.period_s = preload * std::ldexp(1.0, prescale) / kPacerClockHz;
  scan.samples_total = (options & kScanSingleExecution) ? count : 0;
  scan.pending.reserve(kSamplesPerPacket + scan.channels.size());
  for (auto& q : scan_packets_) q.clear();
  scan_ = std::move(scan);
  return true;
}

std::optional<std::chrono::nanoseconds> Usb1408fsModel::nextPacketTime() const {
  if (!scan_.running) return std::nullopt;
  const std::size_t n = scan_.channels.size();
  // Ticks needed until the pending buffer holds a full packet.
  const std::size_t missing = kSamplesPerPacket - std::min(kSamplesPerPacket, scan_.pending.size());
  const std::uint64_t ticks = scan_.ticks_done + (missing + n - 1) / n;
  return scan_.start + std::chrono::nanoseconds(static_cast<std::int64_t>(
                           std::ceil(static_cast<double>(ticks) * scan_.period_s * 1e9)));
}

void Usb1408fsModel::advanceTo(std::chrono::nanoseconds time) {
  if (time <= now_) return;
  now_ = time;
  if (!scan_.running || !connected_) return;
  const double elapsed_s = (now_ - scan_.start).count() * 1e-9;
  const auto due = static_cast<std::uint64_t>(std::floor(elapsed_s / scan_.period_s + 1e-9));
  while (scan_.running && scan_.ticks_done < due) {
    ++scan_.ticks_done;
    const double t = scan_.start.count() * 1e-9 + scan_.ticks_done * scan_.period_s;
    for (const Channel& ch : scan_.channels) {
      if (scan_.samples_total > 0 && scan_.samples_made == scan_.samples_total) break;
      scan_.pending.push_back(wordFor(ch, source_ ? source_(ch, t) : 0.0));
      ++scan_.samples_made;
      if (scan_.pending.size() == kSamplesPerPacket) emitPacket(false);
    }
    if (scan_.samples_total > 0 && scan_.samples_made == scan_.samples_total) {
      if (!scan_.pending.empty()) emitPacket(true);
      scan_.running = false;
    }
  }
}

void Usb1408fsModel::emitPacket(bool final_packet) {
  Packet p;
  p.length = kPacketSize;
  for (std::size_t i = 0; i < scan_.pending.size(); ++i) putU16(&p.bytes[2 * i], scan_.pending[i]);
  putU16(&p.bytes[kScanIndexOffset], scan_.index);
  scan_.pending.clear();
  auto& q = scan_packets_[scan_.next_endpoint];
  scan_.next_endpoint = (scan_.next_endpoint + 1) % scan_packets_.size();
  const bool dropped = drop_.erase(scan_.index) > 0;
  ++scan_.index;
  // Lost data shows only as a gap in the scan index: the status word has no overrun bit (its bits
  // are sync, trigger edge, gated sync, calibration memory unlocked).
  if (dropped || q.size() >= kMaxQueuedPackets) {
    ++scan_.packets_dropped;
    return;
  }
  if (truncate_scan_ > 0) {
    p.length = truncate_scan_;
    truncate_scan_ = 0;
  }
  q.push_back(p);
  ++scan_.packets_sent;
  (void)final_packet;
}

std::optional<Usb1408fsModel::Packet> Usb1408fsModel::takeReply() {
  if (!connected_ || replies_.empty()) return std::nullopt;
  Packet p = replies_.front();
  replies_.pop_front();
  return p;
}

bool Usb1408fsModel::scanDataWaiting(std::uint8_t endpoint) const {
  const int e = endpoint - kScanEndpoints[0];
  return connected_ && e >= 0 && e < 3 && !scan_packets_[e].empty();
}

Usb1408fsModel::Result Usb1408fsModel::takeScanPacket(std::uint8_t endpoint,
                                                      std::optional<Packet>& packet) {
  packet.reset();
  if (!connected_) return Result::kNoDevice;
  const int e = endpoint - kScanEndpoints[0];
  if (e < 0 || e >= 3) return Result::kStall;
  if (scan_stall_ && !scan_packets_[e].empty()) {
    scan_stall_ = false;
    return Result::kStall;
  }
  if (scan_packets_[e].empty()) return Result::kOk;
  packet = scan_packets_[e].front();
  scan_packets_[e].pop_front();
  return Result::kOk;
}

void Usb1408fsModel::dropScanPackets(std::uint16_t first_index, std::uint16_t count) {
  for (std::uint16_t i = 0; i < count; ++i)
    drop_.insert(static_cast<std::uint16_t>(first_index + i));
}

void Usb1408fsModel::unplug() {
  connected_ = false;
  scan_.running = false;
}

void Usb1408fsModel::replug() {
  connected_ = true;
  scan_ = Scan{};
  replies_.clear();
  for (auto& q : scan_packets_) q.clear();
  queue_.clear();
  range_.fill(0);
  dir_ = {1, 1};
  dout_ = {0, 0};
  status_ = 0;
}

}  // namespace zerocal::sim

namespace zerocal::sim {

void Usb1408fsModel::stallNextCommand(std::uint8_t code, int times) {
  stall_code_ = code;
  stall_times_ = times;
}

}  // namespace zerocal::sim
