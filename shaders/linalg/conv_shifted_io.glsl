// The operands and output of nn/conv_shifted_coopmat (linear_coopmat.comp built with CONV_SHIFTED): a stride-1
// convolution with "same" padding as one GEMM per chunk, with no gather (engine/src/tensor/ops_conv_shifted.cpp).
//
// X is the chunk's input repacked channels-last on its zero-padded grid (conv_pack_input.comp with a halo): pixel
// (frame, row, column) of the grid at row (frame·rows_p + row)·wp + column of a [pixels][CP] fp16 matrix. Output
// pixel (t, h, w) of the chunk is grid row m = t·plane + h·wp + w, and tap (dt, dh, dw) reads grid row m + dt·plane +
// dh·wp + dw: for one tap, X shifted by a constant number of rows. K runs tap by tap over CP channels (the weights'
// packed order, W [Cout][tap][CP] as packed at load), CP a multiple of BK, so each step reads one tap: its X rows
// are the GEMM's rows shifted by that tap's offset (x_step_shift), one contiguous 16-byte run per row as in a GEMM.
// Grid rows that are no output pixel (a row's last kw - 1 columns, a frame's last kh - 1 rows) are computed and
// dropped by the epilogue; the largest row read is the grid's last pixel, so no read leaves the chunk.

layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };  // f32, or 16-bit pairs
layout(std430, binding = 3) buffer Yb { float y[]; };               // [.., Cout, F, H, W] at the strides below

layout(push_constant) uniform Push {
  uint M, N, K;          // grid rows up to the chunk's last output pixel, output channels, taps x CP
  uint ldx, ldw;         // CP (X's row), taps x CP (W's row)
  uint x_off, w_off, y_off, bias_off;
  uint x_bs, w_bs;       // 0 (one batch item per dispatch; the GEMM's loads read them)
  uint kw, khw;          // kernel width, kh x kw
  uint wp, plane;        // the grid's row length (W + kw - 1) and frame (its rows x wp)
  uint rows, wo;         // the chunk's output rows and columns
  uint ys_f, ys_h, ys_w, ys_c;  // y's strides in elements
  uint bias_type;        // 0 no bias, 1 f32, 2 f16, 3 bf16
} p;
// X (the repacked grid, XTYPE 1) and W (the weights packed at load) with their loads; X's loads add x_shift.
#include "gemm_operands.glsl"

// Step k0's X shift in elements: its tap's offset on the grid minus the tap's place in K (both times CP).
uint x_step_shift(uint k0) {
  const uint tap = k0 / p.ldx, dt = tap / p.khw, r = tap - dt * p.khw, dh = r / p.kw, dw = r - dh * p.kw;
  return (dt * p.plane + dh * p.wp + dw - tap) * p.ldx;
}

float conv_bias(uint n) {
  const uint i = p.bias_off + n;
  if (p.bias_type == 1u) return uintBitsToFloat(bias[i]);
  const uint u = bias[i >> 1], bits = (i & 1u) == 0u ? (u & 0xffffu) : (u >> 16);
  return p.bias_type == 2u ? unpackHalf2x16(bits).x : uintBitsToFloat(bits << 16);
}

// The sum of grid row m, output channel n: stored (with the bias) where m is an output pixel of the chunk.
void store_conv_output(uint m, uint n, float f) {
  const uint t = m / p.plane, r = m - t * p.plane, h = r / p.wp, w = r - h * p.wp;
  if (h >= p.rows || w >= p.wo) return;
  if (p.bias_type != 0u) f += conv_bias(n);
  y[p.y_off + n * p.ys_c + t * p.ys_f + h * p.ys_h + w * p.ys_w] = f;
}
