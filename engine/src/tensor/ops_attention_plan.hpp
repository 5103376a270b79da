// The planning half of ops::attention (internal to tensor/ops_attention*.cpp): validates a call and decides how
// it runs, from sizes, offsets and the limits in force alone (nothing is bound or recorded): the kernel family
// (flash::plan), the texel kernel's register blocking, the split over head groups, query rows and keys when one
// dispatch would pass a limit, and the groups of head-padded copies when head_dim is not a multiple of 4.
// tensor/ops_attention.cpp records what the returned Prepared says; attention_split_plan() reports it.
#pragma once
#include <cstdint>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_attention_flash.hpp"

namespace dvs::ops::attention_plan {

// Register blocking of shaders/nn/attention.comp (64 invocations per workgroup, each owning `rows` query rows,
// keys taken `keys` at a time). On CPU devices (lavapipe) every texel fetch is a per-lane loop, so each
// fetched K/V chunk should feed several rows: about 512 floats of q rows and accumulators per invocation
// measured best (more rows spill more than they save; keys 4 and 8 per block run alike, 4 compiles faster).
// GPUs keep one row per invocation (registers are the limit there). Heads over 128 (up to 64 vec4s of q and
// of accumulators per row) keep one row per invocation everywhere. Which applies is the device's tuning
// (DeviceTuning::attention_rows_by_head_dim).
struct Blocking {
  uint32_t rows, keys;
};

inline constexpr uint32_t kWorkgroupSize = 64;
inline constexpr VkDeviceSize kTexelOffsetAlign = 256;  // the largest minTexelBufferOffsetAlignment Vulkan allows

int64_t padded_dim(int64_t head_dim);

// Throws the internal error of a call the op cannot run (what: the reason).
[[noreturn]] void fail(const std::string& what);
// Throws the device error of a call no split fits: the device's (or DVS_LIMITS') bindings, texel views or
// allocations are too small for it. Not a bug: a smaller size or a device with larger limits runs.
[[noreturn]] void beyond_limits(const std::string& what);

// Validates an operand against the shape: defined f32 (or f16 where `half_ok`: the flash kernels' out), aligned
// columns inside the row stride, large enough. `vec4`: read or written in place as groups of 4 elements (head_dim a
// multiple of 4; the tensor's byte offset a multiple of 4 elements); else only copied element-wise.
void check_operand(const char* name, const AttentionOperand& a, int64_t batch, int64_t len, int64_t width,
                   bool vec4 = true, bool half_ok = false);

struct Geometry {  // the operand strides of a call, elements
  int64_t qs, ks, vs, os;
};

// A head-padded call runs in groups: batch elements × heads × query rows whose padded copies each fit one
// allocation (four Recorder scratch slots, kPadSlot in ops_attention.cpp).
struct PadPlan {
  int64_t dp = 0;                            // padded head_dim; 0: no padding
  int64_t batch = 0, heads = 0, q_rows = 0;  // one group
  int64_t copies = 0;                        // copy dispatches of the whole call
  uint64_t bytes = 0;                        // the four padded regions of one (the largest) group
};

// The most heads × token rows one copy dispatch may cover: the source window (R32F texels) and the
// destination window (storage) each within one binding (with the worst-case alignment shift), the
// elements written within one grid. Widths are columns per head, strides elements per token row.
struct CopyChunk {
  int64_t heads = 0, rows = 0;
};
CopyChunk copy_chunk(const vk::DeviceCaps& caps, int64_t rows, int64_t heads, int64_t src_stride, int64_t src_w,
                     int64_t dst_stride, int64_t dst_w);

// fn(b0, bn, h0, hn, q0, qn) for every group of a padded call.
template <class F>
void for_each_group(const AttentionShape& s, const PadPlan& pp, F&& fn) {
  for_each_chunk(s.batch, pp.batch, [&](int64_t b0, int64_t bn) {
    for_each_chunk(s.heads, pp.heads, [&](int64_t h0, int64_t hn) {
      for_each_chunk(s.q_len, pp.q_rows, [&](int64_t q0, int64_t qn) { fn(b0, bn, h0, hn, q0, qn); });
    });
  });
}

// The query (and output) token rows of a group as runs of consecutive rows: fn(model_row0, padded_row0, n).
// One run of bn·Lq rows when the group has every query row, else one run of qn rows per batch element.
template <class F>
void for_each_q_run(int64_t b0, int64_t bn, int64_t q_len, int64_t q0, int64_t qn, F&& fn) {
  if (qn == q_len) return fn(b0 * q_len, int64_t(0), bn * q_len);
  for (int64_t b = 0; b < bn; ++b) fn((b0 + b) * q_len + q0, b * qn, qn);
}

// The options of one group's padded call: the bias rows of its heads (and query rows), the mask rows of its
// batch elements. `bias` and `mask` hold the views the returned options point to.
AttentionOptions group_options(const AttentionOptions& opt, const AttentionShape& s, int64_t b0, int64_t bn,
                               int64_t h0, int64_t hn, int64_t q0, int64_t qn, Tensor& bias, Tensor& mask);

// Validates a call and decides how it runs.
struct Prepared {
  Blocking blk{1, 4};
  flash::Plan flash;  // family texel: attention.comp (with its split paths) runs the call
  Geometry geo{};
  AttentionSplit split;
  PadPlan pad;  // pad.dp > 0: head_dim is padded (pad.copies == 0 when there is nothing to do)
};

// A call whose head_dim is a multiple of 4: the kernel reads the operands in place.
Prepared prepare_aligned(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand& q,
                         const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                         const AttentionOptions& opt);

// Any call: prepare_aligned() directly, or the padded groups (plan_pad) and the attention of the first one.
Prepared prepare(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand& q,
                 const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                 const AttentionOptions& opt);

}  // namespace dvs::ops::attention_plan
