#include "digit_font.hpp"

#include <algorithm>
#include <array>

namespace preview {

namespace {

// Five rows of three bits each (bit 2 = left column).
struct Glyph {
  char ch;
  std::array<uint8_t, 5> rows;
};

constexpr Glyph kGlyphs[] = {
    {'0', {7, 5, 5, 5, 7}}, {'1', {2, 6, 2, 2, 7}}, {'2', {7, 1, 7, 4, 7}}, {'3', {7, 1, 7, 1, 7}},
    {'4', {5, 5, 7, 1, 1}}, {'5', {7, 4, 7, 1, 7}}, {'6', {7, 4, 7, 5, 7}}, {'7', {7, 1, 1, 1, 1}},
    {'8', {7, 5, 7, 5, 7}}, {'9', {7, 5, 7, 1, 7}}, {'.', {0, 0, 0, 0, 2}}, {':', {0, 2, 0, 2, 0}},
    {'/', {1, 1, 2, 4, 4}}, {'a', {0, 7, 1, 7, 7}}, {'e', {7, 5, 7, 4, 7}}, {'f', {3, 4, 7, 4, 4}},
    {'k', {4, 5, 6, 5, 5}}, {'m', {0, 7, 7, 5, 5}}, {'p', {7, 5, 7, 4, 4}}, {'s', {7, 4, 7, 1, 7}},
    {'y', {5, 5, 7, 1, 7}}, {'-', {0, 0, 7, 0, 0}},
};

const Glyph* glyph(char c) {
  for (const Glyph& g : kGlyphs)
    if (g.ch == c) return &g;
  return nullptr;
}

void fill(uint8_t* rgba, int width, int height, int x0, int y0, int w, int h, uint8_t value) {
  for (int y = std::max(0, y0); y < std::min(height, y0 + h); ++y)
    for (int x = std::max(0, x0); x < std::min(width, x0 + w); ++x) {
      uint8_t* p = rgba + (size_t(y) * size_t(width) + size_t(x)) * 4;
      p[0] = p[1] = p[2] = value;
      p[3] = 255;
    }
}

}  // namespace

void draw_text(uint8_t* rgba, int width, int height, int x, int y, const std::string& text, int scale) {
  const int advance = 4 * scale;  // 3 columns and a gap
  fill(rgba, width, height, x - scale, y - scale, int(text.size()) * advance + scale, 7 * scale, 0);
  for (size_t i = 0; i < text.size(); ++i) {
    const Glyph* g = glyph(text[i]);
    if (!g) continue;
    for (int row = 0; row < 5; ++row)
      for (int col = 0; col < 3; ++col)
        if (g->rows[size_t(row)] & (4 >> col))
          fill(rgba, width, height, x + int(i) * advance + col * scale, y + row * scale, scale, scale, 255);
  }
}

}  // namespace preview
