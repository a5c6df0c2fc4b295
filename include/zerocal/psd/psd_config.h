// The PSD chain's configuration, and the voltage->mm map in YAML.
//
// PsdConfig is the `daq` section of zerocald's configuration and the only configuration of the
// PSD chain: zerocald reads it from its configuration files, `zerocal psd --config FILE` reads the
// `daq:` section of FILE (zerocald's own file, or config/psd.yaml). Both parse and validate it
// with zerocald's configuration code (zerocal/daemon/config.h: loadDaqSection);
// docs/configuration.md describes every key.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "zerocal/psd/psd.h"

namespace YAML {
class Node;
}

namespace zerocal::psd {

// Which acquisition board reads the PSD, hence which readout the cell factory makes: the
// Measurement Computing USB-1408FS through zerocal's libusb driver.
enum class DaqKind { kUsb1408fs };

struct PsdConfig {
  DaqKind kind = DaqKind::kUsb1408fs;
  std::string serial;  // USB serial-number string; empty = the first USB-1408FS found
  PsdChannels channels;
  double scan_rate_hz = 1000.0;   // scans per second (each scan converts x, y and sum once)
  int samples_per_reading = 100;  // scans averaged into one reading
  double sum_threshold_v = 0.5;   // SUM below this: no spot on the detector
  std::string map_file;  // the PSD's volts-to-mm map (zerocal psd-map); required by hardware

  // A present spot counts as gone only when SUM falls below this (V): the hysteresis keeps a spot
  // on the detector's rim from flickering.
  double sumOffThresholdV() const { return 0.8 * sum_threshold_v; }
};

// The map as YAML: a `psd_map:` document, as `zerocal psd-map --out` writes it. `comment` lines
// go first, prefixed with '#'.
std::string psdMapToYaml(const PsdMap& map, const std::string& comment = {});
// The map from a mapping node (what sits under `psd_map:` or `map:`). Appends problems, prefixed
// with `where`, and returns nullopt when there are any.
std::optional<PsdMap> psdMapFromYaml(const YAML::Node& node, const std::string& where,
                                     std::vector<std::string>& problems);
// A map file written by psdMapToYaml. Throws ConfigError.
PsdMap loadPsdMap(const std::string& path);
// The same from the file's text; `origin` names it in the problems. Throws ConfigError.
PsdMap parsePsdMap(const std::string& yaml_text, const std::string& origin);

}  // namespace zerocal::psd
