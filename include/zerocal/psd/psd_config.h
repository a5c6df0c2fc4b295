// The PSD chain's configuration, and the voltage->mm map in YAML.
//
// PsdConfig is the vendor-free part of the `daq` section of zerocald's configuration (DaqConfig,
// zerocal/daemon/config.h): zerocald reads it from its configuration files, `zerocal-lab psd
// --config FILE` reads the `daq:` section of FILE (zerocald's own file, or config/psd.yaml). Both
// parse and validate it with zerocald's configuration code (loadDaqSection); docs/configuration.md
// describes every key.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "zerocal/psd/psd.h"

namespace YAML {
class Node;
}

namespace zerocal::psd {

// The daq section's vendor-free part: the PSD's light threshold and its map. The board that reads
// the PSD owns its own keys (daq.<kind>, zerocal/cell/daq_kind.h).
struct PsdConfig {
  double sum_threshold_v = 0.5;  // SUM below this: no spot on the detector
  std::string map_file;  // the PSD's volts-to-mm map (zerocal-lab psd-map); required by hardware

  // A present spot counts as gone only when SUM falls below this (V): the hysteresis keeps a spot
  // on the detector's rim from flickering.
  double sumOffThresholdV() const { return 0.8 * sum_threshold_v; }
};

// The map as YAML: a `psd_map:` document, as `zerocal-lab psd-map --out` writes it. `comment` lines
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
