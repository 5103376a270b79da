// Device memory and device limits of the splat renderer (splat.hpp) for one clip, from the sizes alone: how many
// frames go into one chunk, every buffer a chunk allocates, and whether the size can render at all on given
// limits. The renderer chunks a clip with these figures and the memory plan (pipeline/memory_plan.cpp) counts
// them, so `dvs plan`, the preflights and the render agree: what passes `--check` renders.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace dvs::geometry {

// The limits the renderer meets: one storage binding (maxStorageBufferRange), one allocation
// (maxMemoryAllocationSize) and the dispatch's group counts (maxComputeWorkGroupCount x and y). 0 = no limit.
struct SplatLimits {
  uint64_t binding = 0, alloc = 0;
  uint64_t groups_x = 0, groups_y = 0;
  std::string source;  // "device 0 (llvmpipe ...)", for the messages
};

struct SplatBuffer {
  std::string what;
  uint64_t bytes = 0;
};

struct SplatFootprint {
  int64_t chunk_frames = 0;          // frames rendered at once (a chunk's buffers are reused for the next)
  std::vector<SplatBuffer> buffers;  // each one allocation, sized for chunk_frames
  uint64_t total = 0;                // all of them, each rounded up to the allocator's alignment
  SplatBuffer largest;
  std::string problem;               // why this size cannot render on the limits and what helps ("" = it renders)
};

// The accumulation buffer's bytes per pixel and frame (4 words), the renderer's largest buffer: a chunk is as
// many frames as fit one binding and one allocation of it.
constexpr uint64_t kSplatBytesPerPixel = 16;
// Pixels per workgroup along a row (shaders/render/: one frame per dispatch, (W/64, H) groups).
constexpr int64_t kSplatGroupWidth = 64;

// `frames` of height x width; hard_points: the z-buffer mode (--points); float_atomics: accumulation without keys.
SplatFootprint splat_footprint(int64_t frames, int64_t height, int64_t width, bool hard_points, bool float_atomics,
                               const SplatLimits& limits, uint64_t alignment = 256);

}  // namespace dvs::geometry
