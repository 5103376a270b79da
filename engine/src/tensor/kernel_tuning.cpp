#include "tensor/kernel_tuning.hpp"

#include <array>

namespace dvs::ops {
namespace {

// One row per device class: how to recognise it, and its tiles. Measured figures are in the commit
// messages and bench/bench_conv.cpp's output (dvs-bench --group conv).
struct TuningEntry {
  const char* name;
  bool (*matches)(const vk::DeviceCaps&);
  GemmTile conv_f32_weights, conv_16bit_weights;  // large convolutions
  GemmTile conv_small;                            // fewer than 8 * rows output pixels per chunk
  // conv_pack_input: pixels of a row per invocation (0: the whole row). On a CPU driver a vector integer
  // division is a scalar loop per lane, so one invocation per whole row keeps the index arithmetic out of the
  // per-pixel work (11.1 -> 5.1 ms per call in dvs-bench --filter conv_vae at 9x64x96, Mesa 22.3); a GPU
  // wants many threads, so a few pixels each.
  int pack_columns;
};

// CPU drivers (lavapipe, SwiftShader): an 8- or 16-lane subgroup is one SIMD register and every per-lane
// load is a scalar loop, so register blocks that reuse each fetched texel many times win, as long as the
// accumulators (rows x cols registers) and the fetched texels fit the 32 vector registers of AVX-512
// (lavapipe on a 2-core Zen 5, per CPU-second of the FMA peak: 8x2 0.30-0.45, 8x3 0.20-0.30, 16x2 ~0.31,
// 8x4 ~0.33, 16x1 ~0.28; longer channel-loop trips (k_unroll 4) did not help). 8 x 2 (64 channels per
// workgroup with sg_m 2) also divides the VAE's 128/256/512 channels, where 8 x 3 wastes a third at 128.
// With rotations instead of broadcasts (conv_gemm.glsl) 8x2 and 8x4 measured interleaved, twice each, over
// the VAE shapes: 0.28-0.33 and 0.21-0.36, 8x4 ahead on some shapes in one run and behind in the other.
bool cpu_simd(const vk::DeviceCaps& c) { return c.type == VK_PHYSICAL_DEVICE_TYPE_CPU; }
// Anything else: a GPU. Few accumulators per thread keep occupancy; GPUs broadcast uniform loads.
bool any_device(const vk::DeviceCaps&) { return true; }

const std::array<TuningEntry, 2> kTable = {{
    {"cpu-simd", cpu_simd, {8, 2, 2, 0, 1}, {8, 2, 2, 0, 1}, {4, 4, 1, 0, 1}, 0},
    {"gpu", any_device, {8, 2, 2, 0, 1}, {8, 2, 2, 0, 1}, {4, 2, 1, 0, 1}, 4},
}};

// The first entry that matches the device (the last one matches every device).
const TuningEntry& entry_for(const vk::DeviceCaps& caps) {
  for (const TuningEntry& e : kTable)
    if (e.matches(caps)) return e;
  return kTable.back();
}

}  // namespace

int gemm_lanes(const vk::DeviceCaps& c) {
  if (c.subgroup_shuffle && c.subgroup_size == 8) return 0;
  if (c.subgroup_shuffle && c.subgroup_size >= 8 && c.subgroup_size <= 64 && c.subgroup_size % 8 == 0) return 1;
  return 2;
}

GemmTile conv_tile(const vk::DeviceCaps& caps, DType wdt, int64_t outputs, int64_t out_channels,
                   std::string* device_class) {
  const TuningEntry& e = entry_for(caps);
  GemmTile t = wdt == DType::f32 ? e.conv_f32_weights : e.conv_16bit_weights;
  if (outputs < 8 * t.rows) t = e.conv_small;
  t.lanes = gemm_lanes(caps);
  // Few output channels (the decoder's conv_out has 3): all 8 clusters along the pixels and one or two
  // 8-channel columns, instead of a 64-channel tile that is mostly padding.
  if (out_channels <= 16) {
    t.sg_m = 8;
    t.cols = out_channels <= 8 ? 1 : 2;
  }
  if (device_class) *device_class = e.name;
  return t;
}

int conv_pack_columns(const vk::DeviceCaps& caps) { return entry_for(caps).pack_columns; }

}  // namespace dvs::ops
