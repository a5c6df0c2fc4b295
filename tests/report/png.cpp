#include "png.h"

#include <zlib.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace zerocal::test {
namespace {

std::uint32_t be32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 | p[3];
}

int paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

}  // namespace

Image readPng(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> f((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (f.size() < 8 || !std::equal(kSignature, kSignature + 8, f.begin()))
    throw std::runtime_error(path + ": not a PNG file");
  Image img;
  int colour = -1;
  std::vector<std::uint8_t> idat;
  for (std::size_t pos = 8; pos + 12 <= f.size();) {
    const std::uint32_t len = be32(&f[pos]);
    const std::string type(f.begin() + pos + 4, f.begin() + pos + 8);
    const std::uint8_t* data = &f[pos + 8];
    if (pos + 12 + len > f.size()) throw std::runtime_error(path + ": truncated chunk " + type);
    if (type == "IHDR") {
      img.width = static_cast<int>(be32(data));
      img.height = static_cast<int>(be32(data + 4));
      colour = data[9];
      if (data[8] != 8 || (colour != 2 && colour != 6) || data[12] != 0)
        throw std::runtime_error(path + ": only 8-bit RGB/RGBA, not interlaced");
    } else if (type == "IDAT") {
      idat.insert(idat.end(), data, data + len);
    } else if (type == "IEND") {
      break;
    }
    pos += 12 + len;
  }
  if (colour < 0) throw std::runtime_error(path + ": no IHDR");
  const int bpp = colour == 6 ? 4 : 3;
  const std::size_t stride = std::size_t(img.width) * bpp;
  std::vector<std::uint8_t> raw((stride + 1) * img.height);
  uLongf raw_len = raw.size();
  if (uncompress(raw.data(), &raw_len, idat.data(), idat.size()) != Z_OK || raw_len != raw.size())
    throw std::runtime_error(path + ": image data does not inflate");
  std::vector<std::uint8_t> prev(stride, 0), cur(stride);
  img.rgb.resize(std::size_t(img.width) * img.height * 3);
  for (int y = 0; y < img.height; ++y) {
    const std::uint8_t* line = &raw[y * (stride + 1)];
    const int filter = line[0];
    for (std::size_t i = 0; i < stride; ++i) {
      const int a = i >= std::size_t(bpp) ? cur[i - bpp] : 0, b = prev[i],
                c = i >= std::size_t(bpp) ? prev[i - bpp] : 0;
      const int pred = filter == 0   ? 0
                       : filter == 1 ? a
                       : filter == 2 ? b
                       : filter == 3 ? (a + b) / 2
                       : filter == 4 ? paeth(a, b, c)
                                     : -1;
      if (pred < 0) throw std::runtime_error(path + ": bad scanline filter");
      cur[i] = static_cast<std::uint8_t>(line[1 + i] + pred);
    }
    for (int x = 0; x < img.width; ++x)
      for (int k = 0; k < 3; ++k)
        img.rgb[(std::size_t(y) * img.width + x) * 3 + k] = cur[x * bpp + k];
    std::swap(prev, cur);
  }
  return img;
}

}  // namespace zerocal::test
