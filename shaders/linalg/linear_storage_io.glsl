// Shared by the storage-buffer linear kernels (linear_tiled.comp: fp32 FMA; linear_coopmat.comp: tensor
// cores): bindings, push constants, guarded element loads and the epilogue, so the two families differ only
// in how the tile product is formed. Same push block and epilogue meaning as the texel kernel
// (linear.comp); the host (ops_linear.cpp) binds every buffer from an aligned-down offset and passes
// the element offsets.

layout(constant_id = 2) const int WTYPE = 0;  // weight storage: 0 f32, 1 f16, 2 bf16
// Activation storage: 0 f32, 1 f16 (written so by its producer where the GEMM runs on tensor cores).
layout(constant_id = 13) const int XTYPE = 0;

layout(std430, binding = 0) readonly buffer Xb { float xs[]; };  // f32
layout(std430, binding = 0) readonly buffer Xh { uint xh[]; };   // f16 pairs
layout(std430, binding = 1) readonly buffer Wb { uint ws[]; };   // f32 words, or 16-bit pairs
#include "linear_epilogue.glsl"

// X[b][m][k], 0 outside the matrix (the tiles' zero fill: rows past M and K past the end add nothing).
float load_x(uint b, uint m, uint k) {
  if (m >= p.M || k >= p.K) return 0.0;
  const uint e = p.x_off + b * p.x_bs + m * p.ldx + k;
  if (XTYPE == 0) return xs[e];
  const uint u = xh[e >> 1];
  return unpackHalf2x16((e & 1u) == 0u ? u : u >> 16).x;
}

// W[b][n][k] widened to f32 (bf16 -> f32 is a 16-bit left shift), 0 outside the matrix.
float load_w(uint b, uint n, uint k) {
  if (n >= p.N || k >= p.K) return 0.0;
  uint e = p.w_off + b * p.w_bs + n * p.ldw + k;
  if (WTYPE == 0) return uintBitsToFloat(ws[e]);
  uint u = ws[e >> 1], h = (e & 1u) == 0u ? (u & 0xffffu) : (u >> 16);
  return WTYPE == 1 ? unpackHalf2x16(h).x : uintBitsToFloat(h << 16);
}

