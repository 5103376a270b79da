#include "geometry/trajectory_text.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>

#include "dvs/error.hpp"

namespace dvs::geometry {
namespace {

// Length of the UTF-8 sequence starting at s[i], or 0 when it is not a valid one.
size_t utf8_length(std::string_view s, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  const size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k)
    if ((byte(i + k) >> 6) != 0x2) return 0;
  return n;
}

std::string hex_byte(unsigned char c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "\\x%02x", c);
  return buf;
}

}  // namespace

std::string printable_excerpt(std::string_view text, size_t max_chars) {
  std::string out;
  for (size_t i = 0; i < text.size() && i < max_chars; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    out += c >= 0x20 && c < 0x7f ? std::string(1, char(c)) : hex_byte(c);
  }
  return text.size() > max_chars ? out + "..." : out;
}

std::string read_trajectory_text(const std::filesystem::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(path.string() + ": cannot open the trajectory file");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  for (size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    const size_t n = c == 0 ? 0 : utf8_length(text, i);
    if (n == 0)
      throw Error(path.string() + ": not a text file (byte " + hex_byte(c) + " at offset " + std::to_string(i) +
                  "; it starts \"" + printable_excerpt(text, 16) +
                  "\"). A trajectory file is three lines of numbers (theta degrees, phi degrees, r), a .json of "
                  "per-frame poses or a .gltf/.glb camera animation; or give a preset name");
    i += n;
  }
  return text;
}

}  // namespace dvs::geometry
