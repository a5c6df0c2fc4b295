// What every fuzz target shares: the input as text. A target feeds it to one reader and lets
// only that reader's documented refusal (a zerocal::Error) pass; any other exception escapes
// LLVMFuzzerTestOneInput and aborts, and that is a finding (docs/fuzzing.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace zerocal::fuzz {

inline std::string text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace zerocal::fuzz
