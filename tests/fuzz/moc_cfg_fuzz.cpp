// Fuzz target: a controller backup's MOC.cfg (parseMocFile), then what `zerocal apply` reads
// from it and the edit it writes.
#include "fuzz_input.h"
#include "zerocal/apply/moc_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace zerocal::apply;
  try {
    const MocFile file = parseMocFile(zerocal::fuzz::text(data, size), "MOC.cfg");
    robotType(file);
    std::vector<CalOffsetEdit> edits;
    for (int joint = 1; joint <= 6; ++joint) {
      const std::string instance = "rob1_" + std::to_string(joint);
      transmissionOf(file, instance);
      presentCalOffset(file, instance);
      edits.push_back({instance, 0.5 * joint});
    }
    std::vector<MocChange> changes;
    const std::string edited = withCalOffsets(file, edits, &changes);
    diffText(changes);
    parseMocFile(edited, "edited MOC.cfg");  // what apply writes must read back
  } catch (const MocFormatError&) {
  }
  return 0;
}
