// Fuzz target: the simulated cell's world file (parseWorld), as zerocal-sim --world and
// backend.sim_world read it. Robot files it names are looked for in a folder that does not exist.
#include "fuzz_input.h"
#include "zerocal/error.h"
#include "zerocal/sim/world.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const zerocal::World world =
        zerocal::parseWorld(zerocal::fuzz::text(data, size), "fuzz.yaml", "/nonexistent-dir");
    // What the simulator does with an accepted world first: its hash and one beam.
    zerocal::worldHash(world);
    zerocal::beamHit(world, zerocal::Joints{0, 0, 0, 0, 30, 0});
  } catch (const zerocal::ConfigError&) {
  }
  return 0;
}
