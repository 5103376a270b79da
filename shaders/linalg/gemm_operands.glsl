// The storage-buffer GEMM kernels' operands (linear_tiled.comp, linear_coopmat.comp and its conv_shifted_coopmat
// variant, linear_coopmat2.comp): X and W's bindings and their guarded element loads. The including file declares the
// push block `p` first (M, N, K, ldx, ldw, x_off, w_off, x_bs, w_bs: linear_epilogue.glsl's or conv_shifted_io.glsl's).

layout(constant_id = 2) const int WTYPE = 0;  // weight storage: 0 f32, 1 f16, 2 bf16
// Activation storage: 0 f32, 1 f16 (written so by its producer where the GEMM runs on tensor cores).
layout(constant_id = 13) const int XTYPE = 0;

layout(std430, binding = 0) readonly buffer Xb { float xs[]; };  // f32
layout(std430, binding = 0) readonly buffer Xh { uint xh[]; };   // f16 pairs
layout(std430, binding = 1) readonly buffer Wb { uint ws[]; };   // f32 words, or 16-bit pairs

// Added to each X element index of the step being loaded: 0 for a GEMM; the shifted-GEMM convolution sets its
// tap's row offset per step (conv_shifted_io.glsl's x_step_shift).
uint x_shift = 0u;

// X[b][m][k], 0 outside the matrix (the tiles' zero fill: rows past M and K past the end add nothing).
float load_x(uint b, uint m, uint k) {
  if (m >= p.M || k >= p.K) return 0.0;
  const uint e = p.x_off + b * p.x_bs + m * p.ldx + k + x_shift;
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
