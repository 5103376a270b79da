// 8-bit video levels <-> dvs's signed unit range: a channel level v in 0..255 is v/127.5 − 1 in [−1, 1], and a
// value x is written back as round((x + 1)·127.5) clamped to 0..255 (half away from zero, std::lround). One
// definition for the video reader and writer, frame arrays and the embedding API's frames in memory, so a frame
// handed to dvs in memory becomes the same floats as the same frame decoded from a file. No OpenCV here.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace dvs {

inline float level_to_unit(uint8_t level) { return float(level) / 127.5f - 1.0f; }

inline uint8_t unit_to_level(float value) {
  return uint8_t(std::lround(std::clamp((value + 1.0f) * 127.5f, 0.0f, 255.0f)));
}

}  // namespace dvs
