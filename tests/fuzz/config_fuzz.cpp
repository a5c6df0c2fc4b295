// Fuzz target: a zerocald configuration file (applyConfigYaml, as for the main file and every
// drop-in), then the validation of the result and its JSON snapshot (session.json).
#include "fuzz_input.h"
#include "zerocal/daemon/config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zerocal::DaemonConfig config;
  zerocal::ConfigOrigins origins;
  std::vector<std::string> problems;
  zerocal::applyConfigYaml(config, zerocal::fuzz::text(data, size), "fuzz.yaml", "/nonexistent-dir",
                           origins, problems);
  if (problems.empty()) {
    zerocal::validateDaemonConfig(config, origins);
    zerocal::configToJson(config).dump();
  }
  return 0;
}
