// A minimal PNG reader for the browser test: 8-bit RGB or RGBA, not interlaced (what Chromium's
// --screenshot writes). zlib inflates; the scanline filters are undone here.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace zerocal::test {

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3, row by row from the top
  const std::uint8_t* pixel(int x, int y) const { return &rgb[(std::size_t(y) * width + x) * 3]; }
};

// Throws std::runtime_error for a file that is not such a PNG.
Image readPng(const std::string& path);

}  // namespace zerocal::test
