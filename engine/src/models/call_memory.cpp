#include "models/call_memory.hpp"

#include <algorithm>

namespace dvs::models {

uint64_t allocation_bytes(const Shape& shape, uint64_t alignment, uint64_t elem) {
  return align_up(std::max<uint64_t>(uint64_t(shape_numel(shape)) * elem, 1), alignment);
}

void StageMemory::consider(const Shape& shape, uint64_t elem, const std::string& what) {
  const uint64_t bytes = uint64_t(shape_numel(shape)) * elem;
  if (bytes <= largest_bytes) return;
  largest_bytes = bytes;
  largest_elements = shape_numel(shape);
  largest_what = what + " [" + shape_str(shape) + "]" + (elem == 4 ? " f32" : elem == 2 ? " bf16" : "");
}

void StageMemory::consider_buffer(uint64_t bytes, const std::string& what) {
  if (bytes <= largest_bytes) return;
  largest_bytes = bytes;
  largest_elements = int64_t(bytes / 4);
  largest_what = what;
}

}  // namespace dvs::models
