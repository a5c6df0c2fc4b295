// The PSD chain's section of the configuration (YAML), and the voltage->mm map in YAML.
//
//   psd:
//     serial: ""                 # USB-1408FS serial number; empty: the first board found
//     channels:                  # which inputs carry the conditioning board's outputs
//       x:   {mode: differential, input: 0, range_v: 5}
//       y:   {mode: differential, input: 1, range_v: 5}
//       sum: {mode: differential, input: 2, range_v: 5}
//     samples: 64                # per channel, averaged into one reading
//     rate_hz: 16000             # scans per second (x, y and sum each converted once per scan)
//     sum_threshold_v: 0.5       # spot present when SUM rises above this ...
//     sum_off_threshold_v: 0.4   # ... and absent again when it falls below this
//     map_file: psd-map.yaml     # from `zerocal psd-map`, relative to this file; or inline:
//     map: {degree: .., zone_mm: {u: [..], v: [..]}, min_sum_v: .., u: [..], v: [..]}
//
// Every key is optional except that a map needs one of map_file / map (or neither: readings are
// then volts only, which is what a sweep on the rig records). The daemon embeds this section.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "zerocal/psd/psd.h"

namespace YAML {
class Node;
}

namespace zerocal::psd {

struct PsdConfig {
  std::string serial;
  PsdChannels channels;
  std::size_t samples = 64;
  double rate_hz = 16000.0;
  double sum_threshold_v = 0.5;
  double sum_off_threshold_v = 0.4;
  std::string map_file;       // as written (relative to the configuration file)
  std::optional<PsdMap> map;  // loaded from map_file, or inline

  // Every problem with the values, worded for the person editing the file; empty if none.
  std::vector<std::string> problems() const;
  // Throws ConfigError(origin, problems()) if there are any.
  void validate(const std::string& origin) const;
};

// Reads the `psd` section (the node under the `psd:` key). `base_dir` resolves a relative
// map_file. Reports unknown keys, wrong types and every validate() problem together in one
// ConfigError.
PsdConfig parsePsdConfig(const YAML::Node& section, const std::string& origin,
                         const std::string& base_dir);
// A file whose top level holds a `psd:` section (config/psd.yaml). Throws ConfigError.
PsdConfig loadPsdConfig(const std::string& path);

// The map as YAML: a `psd_map:` document, as `zerocal psd-map --out` writes it. `comment` lines
// go first, prefixed with '#'.
std::string psdMapToYaml(const PsdMap& map, const std::string& comment = {});
// The map from a mapping node (what sits under `psd_map:` or `map:`). Appends problems, prefixed
// with `where`, and returns nullopt when there are any.
std::optional<PsdMap> psdMapFromYaml(const YAML::Node& node, const std::string& where,
                                     std::vector<std::string>& problems);
// A map file written by psdMapToYaml. Throws ConfigError.
PsdMap loadPsdMap(const std::string& path);

}  // namespace zerocal::psd
