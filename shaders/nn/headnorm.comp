#version 450
// Per-head LayerNorm of q or k inside a fused buffer: x is [rows, row_stride] and the heads are H slices of
// Dh columns starting at col_offset. Each invocation normalises one (row, head) slice with fp32 two-pass
// statistics and the affine [Dh] shared by all heads (f32/bf16/f16 storage). y has x's layout and may be
// the same buffer (in place): an invocation reads each element before it writes it and touches no other.
// VEC4 (Dh, row_stride, col_offset multiples of 4; Dh = 4*N4 <= 256): the slice moves as vec4 and stays in
// registers between the passes, so it is read from memory once.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize
layout(constant_id = 0) const uint WDTYPE = 0;  // 0 f32, 1 bf16, 2 f16
layout(constant_id = 1) const bool AFFINE = true;
layout(constant_id = 2) const bool VEC4 = false;
layout(constant_id = 3) const uint N4 = 1;  // VEC4: head_dim / 4 (the loops unroll exactly)

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y4[]; };
layout(std430, binding = 2) readonly buffer W { uvec4 w4[]; };
layout(std430, binding = 3) readonly buffer B { uvec4 b4[]; };

layout(push_constant) uniform Push { uint rows, H, Dh, row_stride, col_offset; float eps; } p;

#include "norm_weights.glsl"  // after WDTYPE
WEIGHT_LOADERS(load_w, w4)
WEIGHT_LOADERS(load_b, b4)

float x1(uint i) { return x4[i >> 2][i & 3u]; }

void main() {
  uint id = flat_index();
  if (id >= p.rows * p.H) return;
  uint row = id / p.H, head = id - row * p.H;
  uint base = row * p.row_stride + p.col_offset + head * p.Dh;

  if (VEC4) {
    uint base4 = base >> 2;
    vec4 cache[N4];
    float s = 0.0;
    [[unroll]] for (uint k = 0; k < N4; ++k) {
      cache[k] = x4[base4 + k];
      s += (cache[k].x + cache[k].y) + (cache[k].z + cache[k].w);
    }
    float mean = s / float(4 * N4);
    float q = 0.0;
    [[unroll]] for (uint k = 0; k < N4; ++k) {
      vec4 d = cache[k] - mean;
      q += dot(d, d);
    }
    float rstd = inversesqrt(q / float(4 * N4) + p.eps);
    [[unroll]] for (uint k = 0; k < N4; ++k) {
      vec4 v = (cache[k] - mean) * rstd;
      if (AFFINE) v = v * load_w4(k) + load_b4(k);
      y4[base4 + k] = v;
    }
    return;
  }

  float s = 0.0;
  for (uint i = 0; i < p.Dh; ++i) s += x1(base + i);
  float mean = s / float(p.Dh);
  float q = 0.0;
  for (uint i = 0; i < p.Dh; ++i) {
    float d = x1(base + i) - mean;
    q += d * d;
  }
  float rstd = inversesqrt(q / float(p.Dh) + p.eps);
  for (uint i = 0; i < p.Dh; ++i) {
    float v = (x1(base + i) - mean) * rstd;
    if (AFFINE) v = v * load_w1(i) + load_b1(i);
    y4[(base + i) >> 2][(base + i) & 3u] = v;
  }
}
