// The control port's shared secret: one line in a file only its owner may read.
#pragma once

#include <cstddef>
#include <string>

#include "zerocal/error.h"

namespace zerocal::control {

inline constexpr std::size_t kMinTokenLength = 16;  // characters, surrounding whitespace removed
inline constexpr long kMaxTokenFileBytes = 4096;

// Reads the token from `path` (surrounding whitespace removed). Throws Error, with a message that
// says what to do, when the path is empty, the file is missing, not a regular file, unreadable,
// larger than kMaxTokenFileBytes, empty, shorter than kMinTokenLength, or its mode grants any
// permission to group or others (chmod 600 or 400).
std::string loadToken(const std::string& path);

// Compares in time that depends only on the lengths, not on where the strings first differ, so
// that response times do not reveal a prefix of the token.
bool tokensEqual(const std::string& given, const std::string& expected);

}  // namespace zerocal::control
