#version 450
// q, k or v for the flash attention kernels (ops::attention_heads): from a linear layer's output x, token-major
// [B·L, H·D] f32 (the heads interleaved in each token's row), to y [B, H, L, D] head-major (fp16 or fp32), so that a
// head's rows are one contiguous block and a key tile one contiguous read. Each (token, head) slice of D columns
// goes through, in diffusers' order (CogVideoXAttnProcessor2_0: norm_q/norm_k, then apply_rotary_emb):
//   NORM  LayerNorm over the slice, fp32 two-pass statistics, the affine [D] (f32/bf16/f16) shared by the heads;
//   ROPE  on tokens [rope_first, rope_first + n_rot) of each batch element: interleaved pairs,
//         y = x·cos + rot(x)·sin with rot(x)[2i] = -x[2i+1], rot(x)[2i+1] = x[2i] and tables cos/sin [n_rot, D];
//   Y_F16 rounding to fp16 (nearest even in integer arithmetic, subnormals included: the value float16_t() gives the
//         kernels that convert f32 operands themselves), once, here.
// One invocation per slice (D = 4·N4 ≤ 256), held in registers between the passes: x is read once and y written
// once, instead of the in-place norm, RoPE and cast passes over f32 (three reads and writes of x).
// A dispatch covers `rows` token rows from row0 (ops_norm.cpp cuts x into bindings); y and the tables are bound whole.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize
layout(constant_id = 0) const uint WDTYPE = 0;  // the affine's storage: 0 f32, 1 bf16, 2 f16
layout(constant_id = 1) const bool NORM = false;
layout(constant_id = 2) const bool AFFINE = false;  // NORM only
layout(constant_id = 3) const bool ROPE = false;
layout(constant_id = 4) const bool Y_F16 = false;
layout(constant_id = 5) const uint N4 = 16;  // head_dim / 4 (the loops unroll exactly)

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y4[]; };
layout(std430, binding = 1) writeonly buffer Yh { uvec2 yh[]; };  // Y_F16: 4 halves per element
layout(std430, binding = 2) readonly buffer W { uvec4 w4[]; };
layout(std430, binding = 3) readonly buffer B { uvec4 b4[]; };
layout(std430, binding = 4) readonly buffer C { vec4 cos4[]; };
layout(std430, binding = 5) readonly buffer S { vec4 sin4[]; };

// x_off, y_off: the views' shifts in groups of 4 elements (bound from aligned-down offsets); L: tokens per batch
// element in x and y; row0: x's first row in this dispatch (of B·L).
layout(push_constant) uniform Push {
  uint rows, row0, L, H, rope_first, n_rot, x_off, y_off;
  float eps;
} p;

#include "norm_weights.glsl"  // after WDTYPE
WEIGHT_LOADERS(load_w, w4)
WEIGHT_LOADERS(load_b, b4)
#include "f16.glsl"

void main() {
  const uint id = flat_index();
  if (id >= p.rows * p.H) return;
  const uint local_row = id / p.H, head = id - local_row * p.H;
  const uint row = p.row0 + local_row, b = row / p.L, l = row - b * p.L;

  vec4 v[N4];
  const uint xbase = p.x_off + (local_row * p.H + head) * N4;
  [[unroll]] for (uint k = 0; k < N4; ++k) v[k] = x4[xbase + k];

  if (NORM) {
    float s = 0.0;
    [[unroll]] for (uint k = 0; k < N4; ++k) s += (v[k].x + v[k].y) + (v[k].z + v[k].w);
    const float mean = s / float(4 * N4);
    float q = 0.0;
    [[unroll]] for (uint k = 0; k < N4; ++k) {
      const vec4 d = v[k] - mean;
      q += dot(d, d);
    }
    const float rstd = inversesqrt(q / float(4 * N4) + p.eps);
    [[unroll]] for (uint k = 0; k < N4; ++k) {
      v[k] = (v[k] - mean) * rstd;
      if (AFFINE) v[k] = v[k] * load_w4(k) + load_b4(k);
    }
  }

  if (ROPE && l >= p.rope_first && l - p.rope_first < p.n_rot) {
    const uint t = (l - p.rope_first) * N4;
    [[unroll]] for (uint k = 0; k < N4; ++k) v[k] = v[k] * cos4[t + k] + vec4(-v[k].y, v[k].x, -v[k].w, v[k].z) * sin4[t + k];
  }

  const uint ybase = p.y_off + ((b * p.H + head) * p.L + l) * N4;
  [[unroll]] for (uint k = 0; k < N4; ++k) {
    if (Y_F16) {
      yh[ybase + k] = uvec2(f32_to_f16_bits(v[k].x) | (f32_to_f16_bits(v[k].y) << 16),
                            f32_to_f16_bits(v[k].z) | (f32_to_f16_bits(v[k].w) << 16));
    } else {
      y4[ybase + k] = v[k];
    }
  }
}
