#include "zerocal/usb1408fs/usb1408fs_kind.h"

#include <utility>

#include "zerocal/error.h"
#include "zerocal/usb1408fs/libusb_transport.h"
#include "zerocal/usb1408fs/psd_readout.h"

namespace zerocal::usb1408fs {
namespace {

const settings::Choices<Range> kRanges = {{"20V", Range::kBip20V},     {"10V", Range::kBip10V},
                                          {"5V", Range::kBip5V},       {"4V", Range::kBip4V},
                                          {"2.5V", Range::kBip2_5V},   {"2V", Range::kBip2V},
                                          {"1.25V", Range::kBip1_25V}, {"1V", Range::kBip1V}};

void addChannel(settings::Fields& fields, const std::string& prefix, Channel& channel) {
  fields.push_back(settings::integerField(prefix + "number", channel.number));
  fields.push_back(settings::choiceField<InputMode>(
      prefix + "mode", channel.mode,
      {{"differential", InputMode::kDifferential}, {"single_ended", InputMode::kSingleEnded}}));
  fields.push_back(settings::choiceField(prefix + "range", channel.range, kRanges));
}

}  // namespace

void Usb1408fsSettings::declare(const std::string& prefix, settings::Fields& fields) {
  fields.push_back(settings::textField(prefix + "serial", board.serial));
  addChannel(fields, prefix + "channels.x.", board.channels.x);
  addChannel(fields, prefix + "channels.y.", board.channels.y);
  addChannel(fields, prefix + "channels.sum.", board.channels.sum);
  fields.push_back(settings::realField(prefix + "scan_rate_hz", board.scan_rate_hz));
  fields.push_back(
      settings::integerField(prefix + "samples_per_reading", board.samples_per_reading));
}

void Usb1408fsSettings::check(const std::string& prefix, bool, settings::Checker& check) const {
  const PsdChannels& c = board.channels;
  const std::pair<const char*, const Channel*> channels[] = {
      {"x", &c.x}, {"y", &c.y}, {"sum", &c.sum}};
  const std::string channel_key = prefix + "channels.";
  bool channels_valid = true;
  for (const auto& [name, channel] : channels) {
    const int highest = channel->mode == InputMode::kDifferential ? 3 : 7;
    check.range(channel_key + name + ".number", channel->number, 0, highest);
    channels_valid = channels_valid && channel->number >= 0 && channel->number <= highest;
  }
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = i + 1; j < 3; ++j) {
      const bool shared = sharesTerminal(*channels[i].second, *channels[j].second);
      if (shared)
        check.fail(channel_key + channels[j].first,
                   "uses the same input as " + channel_key + channels[i].first);
      channels_valid = channels_valid && !shared;
    }
  // The board scans consecutive inputs, lowest first (docs/usb1408fs.md): x, y, sum in that order.
  if (channels_valid &&
      (wireChannel(c.y) != wireChannel(c.x) + 1 || wireChannel(c.sum) != wireChannel(c.y) + 1))
    check.fail(prefix + "channels",
               "x, y and sum must be consecutive inputs of one mode in that order (e.g. "
               "differential 0, 1, 2): the USB-1408FS scans a range of inputs");
  // The board converts at most 48 kS/s in all, shared by the three channels of a scan.
  check.positive(prefix + "scan_rate_hz", board.scan_rate_hz, 16000.0);
  check.range(prefix + "samples_per_reading", board.samples_per_reading, 1, 1000000);
}

std::unique_ptr<PsdReadout> Usb1408fsSettings::readout(const psd::PsdMap& map,
                                                       const psd::PsdConfig& psd,
                                                       CellClock& clock) const {
  return std::make_unique<Usb1408fsReadout>(
      [serial = board.serial] { return LibusbTransport::open(serial); }, map, clock, board, psd);
}

DaqKind daqKind() {
  return {"usb-1408fs", "Measurement Computing USB-1408FS through zerocal's libusb driver",
          [] { return std::make_unique<Usb1408fsSettings>(); }};
}

const BoardSettings& boardSettingsOf(const settings::KindSections<DaqSettings>& sections) {
  const auto* board = dynamic_cast<const Usb1408fsSettings*>(sections.find("usb-1408fs"));
  if (!board) throw ConfigError("daq", {"this configuration knows no usb-1408fs section"});
  return board->board;
}

}  // namespace zerocal::usb1408fs
