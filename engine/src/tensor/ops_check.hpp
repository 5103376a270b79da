// Device-side NaN/Inf checks of results (shaders/nn/nonfinite.comp): one scan dispatch per tensor, recorded
// into the caller's recording, writing a count and the first bad index into a small host-visible buffer that
// the host reads once the recording has run. No extra submission and no download of the tensor itself.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "tensor/tensor.hpp"
#include "vk/memory.hpp"

namespace dvs::vk {
class Recorder;
}

namespace dvs::ops {

struct NonFiniteHit {
  std::string what;      // the name given to record()
  Shape shape;           // of the scanned tensor
  uint64_t count = 0;    // NaN or ±Inf elements
  int64_t first = 0;     // flat index of the first one
  std::string message() const;  // "x_init f32 [2,4,8,8]: 3 non-finite values (NaN/Inf), the first at [0,1,2,3] (flat 75)"
};

// "[0,1,2,3]": the multi-index of flat element `flat` of a row-major `shape`.
std::string format_index(const Shape& shape, int64_t flat);

class NonFiniteCheck {
 public:
  explicit NonFiniteCheck(vk::Context& ctx, int slots = 32);

  // Records a scan of `t` (f32, any size) into the next free slot, one dispatch per range: ranges fit one
  // binding under the limits in force, and hold at most `range_bytes` when that is not 0 (tests).
  void record(vk::Recorder& rec, const Tensor& t, const std::string& what, VkDeviceSize range_bytes = 0);
  // The slots recorded since the last clear() that found a non-finite value, in recording order. Call only
  // after the recordings that hold the scans have been submitted and waited for.
  std::vector<NonFiniteHit> hits() const;
  void clear();  // frees every slot (host write: no recording that uses them may be in flight)

 private:
  vk::Context& ctx_;
  vk::Buffer result_;  // [slots][count, first]
  int slots_;
  struct Slot {
    std::string what;
    Shape shape;
  };
  std::vector<Slot> used_;
};

// Scans `tensors` now (one submission) and throws dvs::Error "<where>: <hit message>; <hint>" naming the
// first one holding a NaN or Inf.
void require_finite(vk::Context& ctx, const std::vector<std::pair<const Tensor*, std::string>>& tensors,
                    const std::string& hint = "");

}  // namespace dvs::ops
