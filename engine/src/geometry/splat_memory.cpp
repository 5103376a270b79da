#include "geometry/splat_memory.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace dvs::geometry {
namespace {

std::string bytes_text(uint64_t b) {
  char buf[48];
  if (b >= (1ull << 20)) std::snprintf(buf, sizeof buf, "%.2f MiB", double(b) / double(1ull << 20));
  else if (b >= 1024) std::snprintf(buf, sizeof buf, "%.2f KiB", double(b) / 1024.0);
  else std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(b));
  return buf;
}

std::string hw(int64_t h, int64_t w) { return std::to_string(h) + "x" + std::to_string(w); }

}  // namespace

SplatFootprint splat_footprint(int64_t frames, int64_t H, int64_t W, bool hard_points, bool float_atomics,
                               const SplatLimits& l, uint64_t alignment) {
  SplatFootprint f;
  if (frames < 1 || H < 1 || W < 1) return f;
  const uint64_t pixels = uint64_t(H) * uint64_t(W), frame_bytes = pixels * kSplatBytesPerPixel;
  const std::string of = l.source.empty() ? std::string() : " of " + l.source;
  // The renderer splits a clip over frames, never a frame: one frame's accumulation must fit both limits.
  auto too_big = [&](uint64_t limit, const char* name) {
    // A size of the same aspect that fits: both sides scaled by sqrt(fit / pixels), down to multiples of 8.
    const uint64_t fit = limit / kSplatBytesPerPixel;
    const double scale = std::sqrt(double(fit) / double(pixels));
    const int64_t h = std::max<int64_t>(8, int64_t(double(H) * scale) / 8 * 8), w = std::max<int64_t>(8, int64_t(double(W) * scale) / 8 * 8);
    f.problem = "render: one " + hw(H, W) + " frame needs " + bytes_text(frame_bytes) +
                " for the splat accumulation, over one " + name + " " + bytes_text(limit) + of +
                "; the renderer splits a clip over frames, not a frame: use a smaller --size (at most " +
                std::to_string(fit) + " pixels, e.g. --size " + hw(h, w) + ")";
  };
  if (l.binding && frame_bytes > l.binding) too_big(l.binding, "storage binding: maxStorageBufferRange");
  else if (l.alloc && frame_bytes > l.alloc) too_big(l.alloc, "allocation: maxMemoryAllocationSize");
  const int64_t groups_x = (W + kSplatGroupWidth - 1) / kSplatGroupWidth;
  if (f.problem.empty() && ((l.groups_y && uint64_t(H) > l.groups_y) || (l.groups_x && uint64_t(groups_x) > l.groups_x)))
    f.problem = "render: a " + hw(H, W) + " frame is splatted in one dispatch of " + std::to_string(groups_x) + "x" +
                std::to_string(H) + " workgroups, over maxComputeWorkGroupCount " + std::to_string(l.groups_x) + "x" +
                std::to_string(l.groups_y) + of + ": use a smaller --size (height at most " + std::to_string(l.groups_y) +
                ", width at most " + std::to_string(l.groups_x * kSplatGroupWidth) + ")";
  uint64_t room = std::min(l.binding ? l.binding : UINT64_MAX, l.alloc ? l.alloc : UINT64_MAX);
  f.chunk_frames = std::clamp<int64_t>(int64_t(std::min<uint64_t>(room / frame_bytes, 65535)), 1, frames);
  const uint64_t n = uint64_t(f.chunk_frames), p = n * pixels;
  f.buffers.push_back({"splat frame max", n * 4});
  if (!hard_points) {
    f.buffers.push_back({"splat accumulation", p * 16});
    if (!float_atomics) f.buffers.push_back({"splat keys", p * 4});
  } else {
    f.buffers.push_back({"z-buffer depth keys", p * 4});
    f.buffers.push_back({"z-buffer point keys", p * 4});
  }
  f.buffers.push_back({"render input video", p * 12});
  f.buffers.push_back({"render input depth", p * 4});
  f.buffers.push_back({"render output", p * 12});
  f.buffers.push_back({"render mask", p * 4});
  for (const auto& b : f.buffers) {
    f.total += (b.bytes + alignment - 1) / alignment * alignment;
    if (b.bytes > f.largest.bytes) f.largest = b;
  }
  return f;
}

}  // namespace dvs::geometry
