// Where an installed zerocal finds its files: the configuration folder, /etc/zerocal with the
// prefix /usr (ZEROCAL_CONFDIR, set by CMake on the zerocal::paths target).
#pragma once

namespace zerocal {

inline constexpr const char* kConfigDir = ZEROCAL_CONFDIR;
inline constexpr const char* kDefaultConfigPath = ZEROCAL_CONFDIR "/zerocald.yaml";
inline constexpr const char* kDefaultDropInDir = ZEROCAL_CONFDIR "/zerocald.d";

}  // namespace zerocal
