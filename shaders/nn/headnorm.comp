#version 450
// Per-head LayerNorm of q or k inside a fused buffer: x is [rows, row_stride] and the heads are H slices of
// Dh columns starting at col_offset. Each invocation normalises one (row, head) slice with fp32 two-pass
// statistics and the affine [Dh] shared by all heads (f32/bf16/f16 storage). y has x's layout and may be
// the same buffer (in place): an invocation reads each element before it writes it and touches no other.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize
layout(constant_id = 0) const uint WDTYPE = 0;  // 0 f32, 1 bf16, 2 f16
layout(constant_id = 1) const bool AFFINE = true;

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(std430, binding = 2) readonly buffer W { uint w[]; };
layout(std430, binding = 3) readonly buffer B { uint b[]; };

layout(push_constant) uniform Push { uint rows, H, Dh, row_stride, col_offset; float eps; } p;

float unpack_weight(uint word, uint i) {
  if (WDTYPE == 0) return uintBitsToFloat(word);
  uint half_bits = (i & 1u) != 0u ? (word >> 16) : (word & 0xffffu);
  if (WDTYPE == 1) return uintBitsToFloat(half_bits << 16);
  return unpackHalf2x16(half_bits).x;
}
float load_w(uint i) { return unpack_weight(w[WDTYPE == 0 ? i : i >> 1], i); }
float load_b(uint i) { return unpack_weight(b[WDTYPE == 0 ? i : i >> 1], i); }

void main() {
  uint id = flat_index();
  if (id >= p.rows * p.H) return;
  uint row = id / p.H, head = id - row * p.H;
  uint base = row * p.row_stride + p.col_offset + head * p.Dh;

  float s = 0.0;
  for (uint i = 0; i < p.Dh; ++i) s += x[base + i];
  float mean = s / float(p.Dh);
  float q = 0.0;
  for (uint i = 0; i < p.Dh; ++i) {
    float d = x[base + i] - mean;
    q += d * d;
  }
  float rstd = inversesqrt(q / float(p.Dh) + p.eps);
  for (uint i = 0; i < p.Dh; ++i) {
    float v = (x[base + i] - mean) * rstd;
    if (AFFINE) v = v * load_w(i) + load_b(i);
    y[base + i] = v;
  }
}
