#include "zerocal/usb1408fs/protocol.h"

#include <cmath>
#include <string>

#include "zerocal/usb1408fs/errors.h"

namespace zerocal::usb1408fs {

double fullScaleVolts(Range range) {
  static constexpr double kFullScale[8] = {20.0, 10.0, 5.0, 4.0, 2.5, 2.0, 1.25, 1.0};
  return kFullScale[static_cast<std::uint8_t>(range) & 7];
}

double fullScaleVolts(const Channel& channel) {
  return channel.mode == InputMode::kSingleEnded ? 10.0 : fullScaleVolts(channel.range);
}

std::uint8_t wireChannel(const Channel& channel) {
  return static_cast<std::uint8_t>(channel.mode == InputMode::kSingleEnded ? channel.number + 8
                                                                           : channel.number);
}

std::uint8_t wireRange(const Channel& channel) {
  return channel.mode == InputMode::kSingleEnded ? 0 : static_cast<std::uint8_t>(channel.range);
}

int differentialCode(std::uint16_t word) { return static_cast<std::int16_t>(word) / 4; }

int singleEndedCode(std::uint16_t word) {
  // The firmware's single-ended words carry 13 bits shifted by one; the top of the range is
  // reported through two odd patterns that the vendor code maps like this.
  unsigned u = word;
  if (u > 0x7ffc) {
    u = 0;
  } else if (u > 0x7ff8) {
    u = 0x3fff;
  } else {
    u = (u >> 1) & 0x3fff;
  }
  return static_cast<int>(u) - 0x2000;
}

int rawCode(const Channel& channel, std::uint16_t word) {
  return channel.mode == InputMode::kSingleEnded ? singleEndedCode(word) : differentialCode(word);
}

double codeToVolts(double code, const Channel& channel) {
  return code * fullScaleVolts(channel) / 8191.0;
}

std::uint16_t calibrationAddress(const Channel& channel) {
  if (channel.mode == InputMode::kSingleEnded) {
    return static_cast<std::uint16_t>(kCalSingleEndedBase + channel.number * 8);
  }
  return static_cast<std::uint16_t>(kCalDifferentialBase +
                                    (channel.number * 8 + static_cast<int>(channel.range)) * 8);
}

Pacer computePacer(double rate_hz) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    throw ProtocolError("scan rate must be positive, got " + std::to_string(rate_hz) + " Hz");
  }
  for (int prescale = 0; prescale <= 8; ++prescale) {
    // The drivers that ran on hardware do not subtract 1 from the preload.
    const double preload = std::round(kPacerClockHz / (rate_hz * std::ldexp(1.0, prescale)));
    if (preload <= 0xFFFF) {
      if (preload < 1.0) {
        throw ProtocolError("scan rate " + std::to_string(rate_hz) +
                            " Hz is above the 10 MHz pacer clock");
      }
      Pacer pacer;
      pacer.prescale = static_cast<std::uint8_t>(prescale);
      pacer.preload = static_cast<std::uint16_t>(preload);
      pacer.actual_rate_hz = kPacerClockHz / (preload * std::ldexp(1.0, prescale));
      return pacer;
    }
  }
  throw ProtocolError("scan rate " + std::to_string(rate_hz) +
                      " Hz is below the slowest pacer setting (about 0.6 Hz)");
}

bool sharesTerminal(const Channel& a, const Channel& b) {
  const auto inputs = [](const Channel& c) {
    return c.mode == InputMode::kSingleEnded ? std::array<int, 2>{c.number, c.number}
                                             : std::array<int, 2>{c.number, c.number + 4};
  };
  for (int p : inputs(a))
    for (int q : inputs(b))
      if (p == q) return true;
  return false;
}

}  // namespace zerocal::usb1408fs
