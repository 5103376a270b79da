#version 450
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
#extension GL_EXT_control_flow_attributes : require
// Flash attention: out = softmax(q·kᵀ·scale + bias + mask)·v, keys streamed in blocks with an online softmax
// in fp32 (running max and sum per query row), so no Lq×Lk matrix ever exists.
//
// Work split: every invocation owns R whole query rows (its q rows, running max/sum and output accumulators
// live in its registers) and all invocations of a workgroup walk the keys of one (batch, head) in lockstep.
// K and V rows are read at the same address by every lane (texel fetches, RGBA32F), so nothing crosses
// lanes: no shared memory, no subgroup operations, no barriers. On lavapipe (docs/design.md §8) a texel fetch is a
// per-lane gather whatever the address and a subgroup broadcast costs about as much, so the measured best
// is to have no cross-lane traffic at all and feed each fetched K/V chunk to R rows × 4 FMAs (a first
// design with 8-lane teams sharing rows through broadcasts ran 2.5× slower; barriers that make the
// workgroup's subgroups share key tiles in cache cost more than they save). On GPUs the same-address reads
// are cache broadcasts.
//
// Masked keys get the logit -FLT_MAX (what transformers' finfo.min mask amounts to in fp32): they weigh
// exp(-huge) = 0 unless every key of a row is masked, in which case all logits are equal and the row is the
// mean of v over all Lk keys, as in transformers.
layout(local_size_x = 64) in;

layout(constant_id = 0) const int D4 = 16;            // head_dim / 4
layout(constant_id = 1) const bool HAS_BIAS = false;  // additive bias [H, Lq, Lk]
layout(constant_id = 2) const bool HAS_MASK = false;  // key mask [B, Lk], 0 = masked
layout(constant_id = 3) const int R = 4;              // query rows per invocation
layout(constant_id = 4) const int KB = 8;             // keys per block of the online softmax
// Keys split over several dispatches (a split too long for one binding): the running max, sum and
// accumulators of each (row, head) are carried from one dispatch to the next through State.
layout(constant_id = 5) const bool LOAD_STATE = false;   // continue from State instead of starting afresh
layout(constant_id = 6) const bool STORE_STATE = false;  // leave the running state in State, write no output

const float LOG2E = 1.4426950408889634;
const float MASKED = -3.4028234663852886e38;  // -FLT_MAX

layout(binding = 0) uniform textureBuffer Q;     // RGBA32F texels
layout(binding = 1) uniform textureBuffer K;     // RGBA32F
layout(binding = 2) uniform textureBuffer V;     // RGBA32F
layout(std430, binding = 3) writeonly buffer Out { vec4 o[]; };
layout(binding = 4) uniform textureBuffer Bias;  // R32F [H, Lq, Lk]
layout(binding = 5) uniform textureBuffer Mask;  // R32F [B, Lk]
// Per (row, head) of the dispatch: D4 accumulator vec4s, then (max, sum, 0, 0).
layout(std430, binding = 6) buffer State { vec4 st[]; };

// Offsets and strides in vec4 units. q and out: token-major rows [B, L, H·D]. k and v: row (token) stride
// plus explicit batch and head strides, so they can be token-major like q or repacked head-major
// [B, H, L, D] (attention_pack.comp).
layout(push_constant) uniform Push {
  uint q_len, kv_len, heads;
  uint q_off, q_stride, o_off, o_stride;
  uint k_off, k_stride, k_bstride, k_hstride;
  uint v_off, v_stride, v_bstride, v_hstride;
  float scale;
  // Elements: bias (h, row, key) at bias_off + h·bias_hstride + row·bias_rstride + key; mask (b, key) at
  // mask_off + b·kv_len + key.
  uint bias_off, bias_hstride, bias_rstride, mask_off;
} p;

void main() {
  const uint h = gl_WorkGroupID.y, b = gl_WorkGroupID.z;
  const uint row0 = gl_WorkGroupID.x * (gl_WorkGroupSize.x * R) + gl_LocalInvocationID.x;  // rows row0 + 64·r
  const uint kv_row0 = b * p.kv_len;
  const uint kbase = b * p.k_bstride + h * p.k_hstride + p.k_off;
  const uint vbase = b * p.v_bstride + h * p.v_hstride + p.v_off;

  // My q rows, pre-multiplied by scale·log2(e) so that scores are in the exp2 domain.
  vec4 q[R][D4];
  uint bias_row[R];
  [[unroll]] for (int r = 0; r < R; ++r) {
    uint row = min(row0 + r * gl_WorkGroupSize.x, p.q_len - 1);
    uint base = (b * p.q_len + row) * p.q_stride + p.q_off + h * D4;
    [[unroll]] for (int c = 0; c < D4; ++c) q[r][c] = texelFetch(Q, int(base + c)) * (p.scale * LOG2E);
    bias_row[r] = h * p.bias_hstride + row * p.bias_rstride + p.bias_off;
  }

  float m[R], l[R];
  vec4 acc[R][D4];
  [[unroll]] for (int r = 0; r < R; ++r) {
    m[r] = MASKED;
    l[r] = 0;
    [[unroll]] for (int c = 0; c < D4; ++c) acc[r][c] = vec4(0);
  }
  if (LOAD_STATE) {
    [[unroll]] for (int r = 0; r < R; ++r) {
      uint base = (min(row0 + r * gl_WorkGroupSize.x, p.q_len - 1) * p.heads + h) * (D4 + 1);
      [[unroll]] for (int c = 0; c < D4; ++c) acc[r][c] = st[base + c];
      m[r] = st[base + D4].x;
      l[r] = st[base + D4].y;
    }
  }

  for (uint key0 = 0; key0 < p.kv_len; key0 += KB) {
    // ---- scores of the block's keys (the same keys for every lane) ----
    float s[R][KB];
    [[unroll]] for (int r = 0; r < R; ++r)
      [[unroll]] for (int j = 0; j < KB; ++j) s[r][j] = 0;
    [[unroll]] for (int j = 0; j < KB; ++j) {
      uint kaddr = kbase + min(key0 + j, p.kv_len - 1) * p.k_stride;
      [[unroll]] for (int c = 0; c < D4; ++c) {
        vec4 kv = texelFetch(K, int(kaddr + c));
        [[unroll]] for (int r = 0; r < R; ++r)
          s[r][j] = fma(q[r][c].w, kv.w, fma(q[r][c].z, kv.z, fma(q[r][c].y, kv.y, fma(q[r][c].x, kv.x, s[r][j]))));
      }
    }
    if (HAS_BIAS) {
      [[unroll]] for (int j = 0; j < KB; ++j) {
        uint key = min(key0 + j, p.kv_len - 1);
        [[unroll]] for (int r = 0; r < R; ++r) s[r][j] += texelFetch(Bias, int(bias_row[r] + key)).x * LOG2E;
      }
    }
    if (HAS_MASK) {
      [[unroll]] for (int j = 0; j < KB; ++j) {
        if (texelFetch(Mask, int(p.mask_off + kv_row0 + min(key0 + j, p.kv_len - 1))).x == 0.0) {
          [[unroll]] for (int r = 0; r < R; ++r) s[r][j] = MASKED;
        }
      }
    }

    // ---- online softmax: new running max, rescale what was accumulated, probabilities ----
    const bool full = key0 + KB <= p.kv_len;
    [[unroll]] for (int r = 0; r < R; ++r) {
      float mx = m[r];
      [[unroll]] for (int j = 0; j < KB; ++j) mx = (full || key0 + j < p.kv_len) ? max(mx, s[r][j]) : mx;
      float alpha = exp2(m[r] - mx);
      m[r] = mx;
      float sum = 0;
      [[unroll]] for (int j = 0; j < KB; ++j) {
        s[r][j] = (full || key0 + j < p.kv_len) ? exp2(s[r][j] - mx) : 0.0;
        sum += s[r][j];
      }
      l[r] = l[r] * alpha + sum;
      [[unroll]] for (int c = 0; c < D4; ++c) acc[r][c] *= alpha;
    }

    // ---- acc += p·v ----
    [[unroll]] for (int j = 0; j < KB; ++j) {
      uint vaddr = vbase + min(key0 + j, p.kv_len - 1) * p.v_stride;
      [[unroll]] for (int c = 0; c < D4; ++c) {
        vec4 vv = texelFetch(V, int(vaddr + c));
        [[unroll]] for (int r = 0; r < R; ++r) acc[r][c] = fma(vec4(s[r][j]), vv, acc[r][c]);
      }
    }
  }

  // ---- normalise and store (or leave the state for the next keys) ----
  [[unroll]] for (int r = 0; r < R; ++r) {
    uint row = row0 + r * gl_WorkGroupSize.x;
    if (STORE_STATE) {
      if (row < p.q_len) {
        uint base = (row * p.heads + h) * (D4 + 1);
        [[unroll]] for (int c = 0; c < D4; ++c) st[base + c] = acc[r][c];
        st[base + D4] = vec4(m[r], l[r], 0, 0);
      }
    } else if (row < p.q_len) {
      float inv = 1.0 / l[r];
      uint base = (b * p.q_len + row) * p.o_stride + p.o_off + h * D4;
      [[unroll]] for (int c = 0; c < D4; ++c) o[base + c] = acc[r][c] * inv;
    }
  }
}
