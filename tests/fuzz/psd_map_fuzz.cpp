// Fuzz target: the PSD's volts-to-mm map file (parsePsdMap, as daq.map_file is read); an
// accepted map turns readings into positions and writes back to a file that reads again.
#include "fuzz_input.h"
#include "zerocal/error.h"
#include "zerocal/psd/psd_config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace zerocal::psd;
  PsdMap map;
  try {
    map = parsePsdMap(zerocal::fuzz::text(data, size), "map.yaml");
  } catch (const zerocal::ConfigError&) {
    return 0;
  }
  for (const double x : {-10.0, -1.0, 0.0, 0.3, 10.0}) {
    VoltageReading reading;
    reading.x = x;
    reading.y = -x / 2;
    reading.sum = 4.0;
    reading.x_se = reading.y_se = 1e-4;
    map.apply(reading);
  }
  map.fingerprint();
  parsePsdMap(psdMapToYaml(map), "written.yaml");  // throws: a finding
  return 0;
}
