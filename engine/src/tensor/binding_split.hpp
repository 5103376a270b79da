// Splitting an op's work so that every dispatch stays within the limits in force (the device's, or lower
// under DVS_LIMITS): no binding over maxStorageBufferRange, no texel view over maxTexelBufferElements, no grid
// over maxComputeWorkGroupCount. Recorder::dispatch refuses anything over them, so an op that can meet a large
// tensor walks it in chunks sized here and binds each chunk as its own sub-view.
#pragma once
#include <cstdint>
#include <initializer_list>

#include "tensor/dispatch.hpp"
#include "vk/device_info.hpp"

namespace dvs::ops {

// One operand walked in rows (a row: whatever unit the op advances by, e.g. one token, one channel plane):
// its bytes per row, and the bytes of one texel when it is bound as a texel buffer (0: storage buffer).
struct RowOperand {
  uint64_t row_bytes = 0;
  uint32_t texel_bytes = 0;
};

// Byte alignment every bound sub-view must start at: the larger of minStorageBufferOffsetAlignment and
// minTexelBufferOffsetAlignment (so a chunk can be bound either way).
uint64_t binding_alignment(const vk::DeviceCaps& caps);

// Bytes one binding of an operand may cover: maxStorageBufferRange, or maxTexelBufferElements texels.
uint64_t binding_capacity(const vk::DeviceCaps& caps, uint32_t texel_bytes);

// The most rows per chunk such that each operand's chunk (count · row_bytes) fits one binding, rounded down
// to a multiple of the smallest row count whose bytes are a multiple of binding_alignment() for every
// operand, so that every chunk starts aligned when row 0 does. Never more than `rows` (a whole tensor that
// fits is one chunk). Throws an internal error naming `op` when not even that granule fits.
int64_t rows_per_chunk(const vk::DeviceCaps& caps, const char* op, std::initializer_list<RowOperand> operands,
                       int64_t rows);

// fn(first, count) for consecutive chunks of at most `chunk` covering [0, total).
template <class F>
void for_each_chunk(int64_t total, int64_t chunk, F&& fn) {
  for (int64_t first = 0; first < total; first += chunk) fn(first, first + chunk < total ? chunk : total - first);
}

// Workgroups one dispatch may have in a 1-D grid folded over x and y (grid_1d below).
uint64_t max_groups_1d(const vk::DeviceCaps& caps);

// grid_1d within the limits in force: x up to maxComputeWorkGroupCount[0], the rest over y. Throws an internal
// error when `items` need more than max_groups_1d() groups (the op must split first).
Grid grid_1d(const vk::DeviceCaps& caps, int64_t items, uint32_t local);

// A view of `whole` covering its bytes [first, end) that starts at the aligned-down offset (for chunks whose
// start cannot be aligned). `base` receives the element (of elem_bytes) of `whole` at the view's start, modulo
// 2^32 (shaders subtract it in uint arithmetic, so a start before whole's own offset works too).
vk::BufferView aligned_view(const vk::BufferView& whole, uint64_t first, uint64_t end, uint64_t align,
                            uint32_t elem_bytes, uint32_t& base);

}  // namespace dvs::ops
