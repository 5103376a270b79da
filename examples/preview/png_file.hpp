// A PNG of an RGBA8 image (the whole window, for the example's README): zlib-compressed, 8-bit RGB.
#pragma once
#include <cstdint>
#include <string>

namespace preview {

void write_png(const std::string& path, const uint8_t* rgba, int width, int height);

}  // namespace preview
