#version 450
// Rotary position embedding on a token slice with interleaved pairs (diffusers apply_rotary_emb,
// use_real_unbind_dim=-1): out = x*cos + rot(x)*sin, rot(x)[2i] = -x[2i+1], rot(x)[2i+1] = x[2i].
// x is [B*L, row_stride] with H heads of Dh columns from col_offset; tokens [first, first+n) of every
// batch are rotated with tables cos/sin [n, Dh] shared by the heads. One invocation per (token, pair) -- or
// per (token, two pairs) with VEC4 (Dh, row_stride, col_offset multiples of 4) -- loops over the heads, so
// each table entry is loaded once. y has x's layout and may be the same buffer; rows outside the slice are
// not written.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize
layout(constant_id = 0) const bool VEC4 = false;

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y4[]; };
layout(std430, binding = 2) readonly buffer C { vec4 cos4[]; };
layout(std430, binding = 3) readonly buffer S { vec4 sin4[]; };

layout(push_constant) uniform Push { uint B, L, first, n, H, Dh, row_stride, col_offset; } p;

void main() {
  uint id = flat_index();
  uint units = VEC4 ? p.Dh / 4 : p.Dh / 2;  // vec4s or pairs per head
  uint unit = id % units, rest = id / units;
  uint token = rest % p.n, batch = rest / p.n;
  if (batch >= p.B) return;
  uint row_base = (batch * p.L + p.first + token) * p.row_stride + p.col_offset;
  if (VEC4) {
    uint te = (token * p.Dh) / 4 + unit;
    vec4 c = cos4[te], s = sin4[te];
    for (uint h = 0; h < p.H; ++h) {
      uint e = (row_base + h * p.Dh) / 4 + unit;
      vec4 v = x4[e];
      y4[e] = v * c + vec4(-v.y, v.x, -v.w, v.z) * s;
    }
    return;
  }
  uint te = token * p.Dh + 2 * unit;
  float c0 = cos4[te >> 2][te & 3u], c1 = cos4[(te + 1) >> 2][(te + 1) & 3u];
  float s0 = sin4[te >> 2][te & 3u], s1 = sin4[(te + 1) >> 2][(te + 1) & 3u];
  for (uint h = 0; h < p.H; ++h) {
    uint e = row_base + h * p.Dh + 2 * unit;
    float x0 = x4[e >> 2][e & 3u], x1 = x4[(e + 1) >> 2][(e + 1) & 3u];
    y4[e >> 2][e & 3u] = x0 * c0 - x1 * s0;
    y4[(e + 1) >> 2][(e + 1) & 3u] = x1 * c1 + x0 * s1;
  }
}
