#version 450
// Rotary position embedding on a token slice with interleaved pairs (diffusers apply_rotary_emb,
// use_real_unbind_dim=-1): out = x*cos + rot(x)*sin, rot(x)[2i] = -x[2i+1], rot(x)[2i+1] = x[2i].
// x is [B*L, row_stride] with H heads of Dh columns from col_offset; tokens [first, first+n) of every
// batch are rotated with tables cos/sin [n, Dh] shared by the heads. One invocation per pair; y has x's
// layout and may be the same buffer. Rows outside the slice are not written.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(std430, binding = 2) readonly buffer C { float cos_t[]; };
layout(std430, binding = 3) readonly buffer S { float sin_t[]; };

layout(push_constant) uniform Push { uint B, L, first, n, H, Dh, row_stride, col_offset; } p;

void main() {
  uint id = flat_index();
  uint pairs = p.Dh / 2;
  uint pair = id % pairs, rest = id / pairs;
  uint head = rest % p.H;
  rest /= p.H;
  uint token = rest % p.n, batch = rest / p.n;
  if (batch >= p.B) return;
  uint e = (batch * p.L + p.first + token) * p.row_stride + p.col_offset + head * p.Dh + 2 * pair;
  uint te = token * p.Dh + 2 * pair;
  float x0 = x[e], x1 = x[e + 1];
  y[e] = x0 * cos_t[te] - x1 * sin_t[te];
  y[e + 1] = x1 * cos_t[te + 1] + x0 * sin_t[te + 1];
}
