// Fuzz target: a session's journal (parseJournal, which readJournal reads a journal.jsonl with),
// line by line as a resume reads it.
#include <spdlog/spdlog.h>

#include "fuzz_input.h"
#include "zerocal/store/journal.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool quiet = [] {  // a dropped torn line is warned about: not for every input
    spdlog::set_level(spdlog::level::off);
    return true;
  }();
  (void)quiet;
  try {
    zerocal::parseJournal(zerocal::fuzz::text(data, size), "journal.jsonl");
  } catch (const zerocal::JournalError&) {
  }
  return 0;
}
