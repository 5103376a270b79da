#include "tensor/binding_split.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "dvs/error.hpp"

namespace dvs::ops {

uint64_t binding_alignment(const vk::DeviceCaps& caps) {
  return std::max<uint64_t>({4, caps.min_storage_buffer_offset_alignment, caps.min_texel_buffer_offset_alignment});
}

uint64_t binding_capacity(const vk::DeviceCaps& caps, uint32_t texel_bytes) {
  if (texel_bytes == 0) return caps.max_storage_buffer_range;
  return std::min<uint64_t>(caps.max_storage_buffer_range, caps.max_texel_buffer_elements * texel_bytes);
}

int64_t rows_per_chunk(const vk::DeviceCaps& caps, const char* op, std::initializer_list<RowOperand> operands,
                       int64_t rows) {
  const uint64_t align = binding_alignment(caps);
  uint64_t granule = 1, most = uint64_t(std::max<int64_t>(rows, 1));
  for (const RowOperand& o : operands) {
    if (o.row_bytes == 0) continue;
    granule = std::lcm(granule, align / std::gcd(align, o.row_bytes));
    most = std::min(most, binding_capacity(caps, o.texel_bytes) / o.row_bytes);
  }
  if (most >= uint64_t(rows)) return std::max<int64_t>(rows, 1);
  most = most / granule * granule;
  if (most == 0)
    throw Error(std::string("internal: ") + op + ": not even " + std::to_string(granule) +
                " rows (the alignment granule) fit one binding of " + std::to_string(caps.max_storage_buffer_range) +
                " bytes / " + std::to_string(caps.max_texel_buffer_elements) + " texels");
  return int64_t(most);
}

uint64_t max_groups_1d(const vk::DeviceCaps& caps) {
  return uint64_t(caps.max_workgroup_count[0]) * caps.max_workgroup_count[1];
}

Grid grid_1d(const vk::DeviceCaps& caps, int64_t items, uint32_t local) {
  const uint64_t gx_max = caps.max_workgroup_count[0], gy_max = caps.max_workgroup_count[1];
  const uint64_t groups = (uint64_t(items) + local - 1) / local;
  Grid g;
  if (groups <= gx_max) {
    g.x = uint32_t(std::max<uint64_t>(groups, 1));
  } else {
    g.x = uint32_t(gx_max);
    const uint64_t gy = (groups + gx_max - 1) / gx_max;
    if (gy > gy_max)
      throw Error("internal: a dispatch of " + std::to_string(items) + " items in groups of " + std::to_string(local) +
                  " needs more than maxComputeWorkGroupCount allows (split the op)");
    g.y = uint32_t(gy);
  }
  if (items <= 0) g.x = 0;
  return g;
}

// A view of `whole` covering its bytes [first, end) that starts at the aligned-down offset. `base` receives
// the element (of elem_bytes) of `whole` at the view's start, modulo 2^32 (the shaders subtract it in uint
// arithmetic, so a start before whole's own offset works too).
vk::BufferView aligned_view(const vk::BufferView& whole, uint64_t first, uint64_t end, uint64_t align,
                            uint32_t elem_bytes, uint32_t& base) {
  const uint64_t start = (whole.offset + first) / align * align;
  vk::BufferView v = whole;
  v.offset = start;
  v.size = (whole.offset + end - start + 3) / 4 * 4;
  if (whole.mapped) v.mapped = whole.mapped - whole.offset + start;
  base = uint32_t(uint64_t(int64_t(start) - int64_t(whole.offset)) / elem_bytes);
  if (start < whole.offset) base = uint32_t(-int64_t((whole.offset - start) / elem_bytes));
  return v;
}

}  // namespace dvs::ops
