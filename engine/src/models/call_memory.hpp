// One model call's device memory as the from-config planners figure it (no weights read, no device): the
// planner's activation figure, the tensors the call allocates around it, and its largest single tensor (each
// tensor is one allocation, so that one must fit maxMemoryAllocationSize). pipeline/memory_plan adds the calls
// of a run up; models/cogvideox/cogvideox_memory makes them for CogVideoX's networks.
#pragma once
#include <cstdint>
#include <string>

#include "io/host_tensor.hpp"

namespace dvs::models {

// Bytes as the device allocator reserves them: rounded up to its alignment.
inline uint64_t align_up(uint64_t bytes, uint64_t alignment) { return (bytes + alignment - 1) / alignment * alignment; }

// Device bytes of one tensor of `elem`-byte elements as the allocator reserves them (never less than one byte).
uint64_t allocation_bytes(const Shape& shape, uint64_t alignment, uint64_t elem = 4);

// One model call: `working` is the planner's activation figure (arena / VAE working set), `io` the tensors the
// call allocates around it (inputs, outputs, tables); total = the call's device peak above the weights.
struct StageMemory {
  std::string name;      // "t5_encode", "transformer_cfg", "transformer_inversion", "vae_encode", "vae_decode"
  std::string what;      // human description with shapes
  uint64_t working = 0, io = 0;
  uint64_t total() const { return working + io; }
  // The largest single tensor the call binds (weights, activations, inputs, outputs): ops split a tensor
  // over several bindings / texel views, but each tensor is one allocation.
  uint64_t largest_bytes = 0;
  int64_t largest_elements = 0;
  std::string largest_what;
  // Non-empty when the call cannot run at all under the limits planned for (an op finds no split of its
  // bindings): the reason, and the byte figures above are not meaningful.
  std::string problem;

  // Keeps the larger of the largest tensor so far and `shape` (`elem` bytes each), described as `what`.
  void consider(const Shape& shape, uint64_t elem, const std::string& what);
  // The same for a buffer a model's planner sized (`what` names it with its shape; f32 texels).
  void consider_buffer(uint64_t bytes, const std::string& what);
};

}  // namespace dvs::models
