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
};

// CPU drivers (lavapipe, SwiftShader): an 8- or 16-lane subgroup is one SIMD register and every per-lane
// load is a scalar loop, so tall register blocks that reuse each fetched texel many times win; the
// accumulators (rows x cols registers) must still fit the 32 vector registers of AVX-512 (16 of AVX2).
bool cpu_simd(const vk::DeviceCaps& c) { return c.type == VK_PHYSICAL_DEVICE_TYPE_CPU; }
// Anything else: a GPU. Few accumulators per thread keep occupancy; GPUs broadcast uniform loads.
bool any_device(const vk::DeviceCaps&) { return true; }

const std::array<TuningEntry, 2> kTable = {{
    {"cpu-simd", cpu_simd, {8, 3, 2, 0}, {8, 3, 2, 0}, {4, 4, 1, 0}},
    {"gpu", any_device, {8, 2, 2, 0}, {8, 2, 2, 0}, {4, 2, 1, 0}},
}};

}  // namespace

int gemm_lanes(const vk::DeviceCaps& c) {
  if (c.subgroup_shuffle && c.subgroup_size == 8) return 0;
  if (c.subgroup_shuffle && c.subgroup_size >= 8 && c.subgroup_size <= 64 && c.subgroup_size % 8 == 0) return 1;
  return 2;
}

GemmTile conv_tile(const vk::DeviceCaps& caps, DType wdt, int64_t outputs, std::string* device_class) {
  for (const TuningEntry& e : kTable) {
    if (!e.matches(caps)) continue;
    GemmTile t = wdt == DType::f32 ? e.conv_f32_weights : e.conv_16bit_weights;
    if (outputs < 8 * t.rows) t = e.conv_small;
    t.lanes = gemm_lanes(caps);
    if (device_class) *device_class = e.name;
    return t;
  }
  return {};
}

}  // namespace dvs::ops
