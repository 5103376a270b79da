#include "png_file.hpp"

#include <zlib.h>

#include <fstream>
#include <stdexcept>
#include <vector>

namespace preview {

namespace {

void put32(std::vector<uint8_t>& out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(uint8_t(v >> s));
}

void chunk(std::ofstream& f, const char* type, const std::vector<uint8_t>& data) {
  std::vector<uint8_t> c;
  put32(c, uint32_t(data.size()));
  c.insert(c.end(), type, type + 4);
  c.insert(c.end(), data.begin(), data.end());
  put32(c, uint32_t(crc32(0, c.data() + 4, uInt(c.size() - 4))));  // over type and data
  f.write(reinterpret_cast<const char*>(c.data()), std::streamsize(c.size()));
}

}  // namespace

void write_png(const std::string& path, const uint8_t* rgba, int width, int height) {
  // Each row: filter byte 1 ("Sub": every byte minus the same channel of the pixel to its left, which makes
  // smooth images compress several times better), then RGB.
  std::vector<uint8_t> raw;
  raw.reserve(size_t(height) * (size_t(width) * 3 + 1));
  for (int y = 0; y < height; ++y) {
    raw.push_back(1);
    for (int x = 0; x < width; ++x) {
      const uint8_t* p = rgba + (size_t(y) * size_t(width) + size_t(x)) * 4;
      for (int c = 0; c < 3; ++c) raw.push_back(uint8_t(p[c] - (x > 0 ? p[c - 4] : 0)));
    }
  }
  uLongf packed_size = compressBound(uLong(raw.size()));
  std::vector<uint8_t> packed(packed_size);
  if (compress2(packed.data(), &packed_size, raw.data(), uLong(raw.size()), 9) != Z_OK)
    throw std::runtime_error(path + ": zlib could not compress the image");
  packed.resize(packed_size);
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot write the file (is the folder writable?)");
  f.write("\x89PNG\r\n\x1a\n", 8);
  std::vector<uint8_t> ihdr;
  put32(ihdr, uint32_t(width));
  put32(ihdr, uint32_t(height));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8 bits, RGB, deflate, no filter method, no interlace
  chunk(f, "IHDR", ihdr);
  chunk(f, "IDAT", packed);
  chunk(f, "IEND", {});
  if (!f) throw std::runtime_error(path + ": writing failed (disk full?)");
}

}  // namespace preview
