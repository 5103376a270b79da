// Attention: out = softmax(q·kᵀ·scale + bias + mask)·v per (batch, head), flash-style (online softmax in
// fp32, keys streamed in blocks): memory is O(sequence), no Lq×Lk score matrix is ever stored.
//
// Layout: the models produce q, k, v from linear layers as [B, L, H·D] (token-major, heads interleaved):
// element (b, l, h, d) lives at (b·L + l)·row_stride + column_offset + h·D + d. A fused QKV GEMM output
// [B, L, 3·H·D] is used in place by giving q, k, v as column slices of it (offsets 0, H·D, 2·H·D, row
// stride 3·H·D). The output is written in the same layout (usually a contiguous [B, Lq, H·D]).
//
// head_dim: any value from 1 to 256. The kernel reads whole vec4s of each head, so a head_dim that is not a
// multiple of 4 is padded: q, k and v are copied into recording scratch with each head widened to
// Dp = D rounded up to 4 columns (zeros in the padding, which change neither q·k nor p·v; the scale is
// options.scale, never derived from D), the attention runs there and the first D columns of each head are
// copied back into out. A multiple of 4 runs in place, as always.
#pragma once
#include <cstdint>

#include "tensor/kernel_tuning.hpp"
#include "tensor/tensor.hpp"
#include "vk/device_info.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// Rows of a [B, L, ·] f32 tensor holding H heads of D columns each, starting at column_offset. Where
// attention_takes_f16() says so (a flash kernel runs the call): q, k and v (both) and out may be f16 (the tensor
// cores' operand type, the next GEMM's X; byte offsets then multiples of 8), and q, k and v head-major.
struct AttentionOperand {
  Tensor t;
  // Elements. Multiples of 4 (and the tensor's byte offset a multiple of 16) when head_dim is a multiple of
  // 4; any values otherwise (the operands are then copied, see above).
  int64_t column_offset = 0;
  int64_t row_stride = 0;  // elements between consecutive tokens; 0 = H·D (contiguous)
  // [B, H, L, D] contiguous from the tensor's start instead (ops::attention_heads writes it): element (b, l, h, d) at
  // ((b·H + h)·L + l)·D + d; column_offset and row_stride 0. Each head's rows are one block: a key tile is one read.
  bool head_major = false;
};

struct AttentionShape {
  int64_t batch = 1;
  int64_t heads = 1;
  int64_t head_dim = 64;  // any value from 1 to 256 (not a multiple of 4: padded, see above)
  int64_t q_len = 0;
  int64_t kv_len = 0;
};

struct AttentionOptions {
  float scale = 1.0f;                // logits = q·k·scale (T5: 1, CogVideoX: 1/sqrt(D))
  const Tensor* bias = nullptr;      // f32 [H, Lq, Lk] added to the scaled logits, shared by the batch
  const Tensor* key_mask = nullptr;  // f32 [B, Lk]: 0 = masked key, anything else = attend
  uint32_t rows_per_invocation = 0;  // register blocking; 0 = chosen per device (tests force other values)
  // Optional f32 scratch of at least attention_workspace_elements(shape) elements. When given, K and V are
  // first repacked head-major [B, H, Lk, D] into it (one extra memory-bound dispatch; per batch element, or
  // per head group, when the call is split) and streamed from there.
  // Worth it on CPU devices (lavapipe) with many interleaved heads at long lengths, where each head's K/V
  // rows are far apart in the token-major layout (measured ~2× faster at H=48, L=2048); pointless on GPUs.
  const Tensor* workspace = nullptr;
};

// Elements the caller must provide as a workspace: one batch element's K and V head-major (2·H·Lk·D, with D
// rounded up to a multiple of 4) plus alignment room; never more, whatever the batch. A workspace of
// 2·B·H·Lk·D repacks the whole batch at once when it fits one binding.
int64_t attention_workspace_elements(const AttentionShape& shape);

// Whether giving a workspace is expected to pay on this device: CPU devices with several heads and long
// key sequences (H=48, L=2048, fused QKV on lavapipe: 0.28 → 0.51 of the FMA peak). False on GPUs.
bool attention_workspace_helps(const vk::DeviceCaps& caps, const AttentionShape& shape);

// Records the attention of q [B, Lq, H·D], k and v [B, Lk, H·D] into out [B, Lq, H·D] (all f32, layouts as
// above). A masked key weighs 0; a row whose keys are ALL masked returns the mean of v over all Lk keys
// (what transformers computes when it adds finfo(float32).min to every logit of the row). Lk = 0 is an
// error; Lq = 0 or B = 0 records nothing.
void attention(vk::Recorder& rec, const AttentionShape& shape, const AttentionOperand& q, const AttentionOperand& k,
               const AttentionOperand& v, const AttentionOperand& out, const AttentionOptions& options = {});

// How attention() cuts a call to stay within the limits in force (no binding over maxStorageBufferRange or
// maxTexelBufferElements, no grid over maxComputeWorkGroupCount). `whole`: one dispatch as always (plus one
// repack with a workspace). Otherwise one batch element at a time, `head_group` heads at a time; q rows in
// chunks of `q_rows`; keys in chunks of `keys` (< Lk only when one head's keys do not fit a binding: the
// online-softmax state is carried between dispatches, in whole key blocks where a binding holds one, so
// results stay bitwise equal to the whole call; chunks under one block differ by rounding only);
// K/V repacked head-major (`repack`, in chunks of `pack_rows` token rows) when given a workspace or when one
// head's keys, strided through the token-major rows, do not fit a binding. Without a workspace, the repack
// goes to Recorder scratch of at most 2 bindings (within the allocation limit): `scratch_bytes` (with the
// running state of split keys), for memory planners.
//
// A head_dim that is not a multiple of 4 (padded_head_dim > 0) runs as: padded copies of q, k, v (Recorder
// scratch, one allocation each, `scratch_bytes` counts them too), the attention on those, the copy back into
// out. When the padded copies of the whole call do not fit one allocation each, the call runs in groups of
// `pad_batch` batch elements × `pad_heads` heads × `pad_q_rows` query rows (query rows are cut only one head
// at a time); each copy is cut into chunks that fit one binding and one grid. `pad_copies`: the copy
// dispatches of the whole call (4 when nothing is cut). The fields above then describe the attention of one
// (the first, largest) group on its padded operands; `whole` says that nothing at all is cut: one group,
// 4 copies, one attention dispatch (plus a repack with a workspace).
//
// `family`: the kernel that runs the call (of the first group, when padded). tiled / coopmat
// (DeviceTuning::attention, shaders/nn/attention_flash*.comp) take only calls without bias or key mask that
// fit one dispatch (storage bindings): always `whole`. Every other call runs on the texel kernel.
struct AttentionSplit {
  KernelFamily family = KernelFamily::texel;
  bool whole = true, repack = false;
  int64_t head_group = 0, q_rows = 0, keys = 0, pack_rows = 0;
  uint64_t scratch_bytes = 0;
  // The two Recorder::scratch requests behind scratch_bytes, as the call makes them (bytes before the allocator's
  // rounding; 0 when not made): head-major K/V of one head group, and the running state of split keys.
  uint64_t kv_scratch_request = 0, state_scratch_request = 0;
  int64_t padded_head_dim = 0;  // 0: head_dim is a multiple of 4, no padding
  int64_t pad_batch = 0, pad_heads = 0, pad_q_rows = 0, pad_copies = 0;
};
AttentionSplit attention_split_plan(const vk::DeviceCaps& caps, const AttentionShape& shape, const AttentionOperand& q,
                                    const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                                    const AttentionOptions& options = {});

// The same for the transformer's and T5's layout (q|k|v fused [B, Lq, 3·H·D], out contiguous [B, Lq, H·D],
// Lq = Lk; T5 with a bias [H, Lq, Lk] and a key mask [B, Lk]), from shapes alone: memory planners add its
// scratch_bytes to a call's figure.
AttentionSplit attention_split_plan_fused(const vk::DeviceCaps& caps, const AttentionShape& shape, bool bias = false,
                                          bool key_mask = false);

// The same for separate contiguous operands (q and out [B, Lq, H·D], k and v [B, Lk, H·D]: the CogVideoX
// transformer's query chunks against the whole sequence's keys).
AttentionSplit attention_split_plan_contiguous(const vk::DeviceCaps& caps, const AttentionShape& shape);

// Whether attention() takes this call's operands in f16 and q, k, v head-major on this device: the call (its operands
// given in f32, token-major, at byte offsets that are multiples of 8) runs on a flash kernel (tiled or tensor cores:
// DeviceTuning::attention, within the limits in force; f16 or head-major operands need no more bytes) and head_dim is
// a multiple of 4 (no padded copies). An f16 out holds the f32 out rounded to nearest even; f16 or head-major q, k and
// v give the result of f32 token-major ones holding the same values. The texel kernel and the padded path refuse
// f16 and head-major operands.
bool attention_takes_f16(const vk::DeviceCaps& caps, const AttentionShape& shape, const AttentionOperand& q,
                         const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                         const AttentionOptions& options = {});

// Contiguous convenience form: q [B, Lq, H·D], k and v [B, Lk, H·D], out [B, Lq, H·D].
void attention(vk::Recorder& rec, const Tensor& q, const Tensor& k, const Tensor& v, const Tensor& out,
               int64_t heads, const AttentionOptions& options = {});

// q, k or v (which = 0, 1, 2) as a column slice of a fused projection [B, L, 3·H·D] laid out [q | k | v].
AttentionOperand fused_qkv_operand(const Tensor& qkv, int which, int64_t heads, int64_t head_dim);

}  // namespace dvs::ops
