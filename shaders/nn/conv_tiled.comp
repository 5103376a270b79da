#version 450
#extension GL_EXT_control_flow_attributes : require
#extension GL_GOOGLE_include_directive : require
// Convolution as an implicit GEMM for GPUs (the "tiled" family, kernel_tuning.hpp): the same GEMM, the
// same repacked operands and the same push constants as conv_gemm.comp, but read through storage buffers
// (no 2^27-element texel-view cap) and staged through shared memory:
//   Y[m, n] = bias[n] + sum_k X[m, k] W[n, k],  m = output pixel of the chunk, n = output channel,
//   k = tap * CP + input channel (CP = Cin rounded up to 8; the weights are [Cout][tap][CP], so W[n, k] is
//   packed element n * K + k with K = taps * CP).
// A workgroup of 256 invocations (16 x 16) computes BM = 16*TM pixels x BN = 16*TN channels; per step of
// BK = 16 reduction elements it gathers the input tile (each invocation keeps one pixel m = t % BM for the
// whole loop and loads a vec4 of 4 channels of one tap: 4 channels never straddle a tap since CP % 8 == 0)
// and the weight tile into shared memory, then each invocation accumulates a TM x TN register block with
// fp32 FMA: pixels tx + 16i, channels ty + 16j, so that neighbouring invocations store neighbouring
// pixels (coalesced in the channels-first layouts). Reduction elements past K read as zero.
layout(local_size_x = 256) in;

layout(constant_id = 0) const int TM = 4;     // pixels per invocation (BM = 16 * TM: 32, 64 or 128)
layout(constant_id = 1) const int TN = 4;     // channels per invocation (BN = 16 * TN)
layout(constant_id = 2) const int WTYPE = 2;  // weight storage: 0 f32, 1 f16, 2 bf16
layout(constant_id = 3) const int BTYPE = 2;  // bias storage (conv_bias.glsl): 0 f32, 1 f16, 2 bf16

const int BM = 16 * TM, BN = 16 * TN, BK = 16;
const int SA = BM * 4 > 256 ? BM * 4 / 256 : 1;  // vec4 loads per invocation per step (input, weights)
const int SB = BN * 4 > 256 ? BN * 4 / 256 : 1;

layout(std430, binding = 0) readonly buffer X { vec4 x[]; };    // packed input chunk + one zero pixel
layout(std430, binding = 1) readonly buffer W { uint w[]; };    // packed weights, the stored dtype
layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };
layout(std430, binding = 3) buffer Y { float y[]; };

// Identical to conv_gemm.comp's (record_conv fills both the same way).
layout(push_constant) uniform Push {
  uint M, N, cp, kt, kh, kw, stride, up, wo, rows, oh0;
  int pad_top, pad_left;
  uint in_h, in_w, src_r0, src_rows, src_w, zero_texel, y_base;
  uint ys_f, ys_h, ys_w, ys_c, has_bias, n_base, accumulate, ow0, src_c0;
} p;

shared float As[BK][BM];
shared float Bs[BK][BN];

#include "conv_bias.glsl"

// Four consecutive packed weights from element e (a multiple of 4).
vec4 w4(uint e) {
  if (WTYPE == 0) return vec4(uintBitsToFloat(w[e]), uintBitsToFloat(w[e + 1u]), uintBitsToFloat(w[e + 2u]), uintBitsToFloat(w[e + 3u]));
  uint a = w[e >> 1], b = w[(e >> 1) + 1u];
  if (WTYPE == 1) return vec4(unpackHalf2x16(a), unpackHalf2x16(b));
  return vec4(uintBitsToFloat(a << 16), uintBitsToFloat(a & 0xffff0000u), uintBitsToFloat(b << 16), uintBitsToFloat(b & 0xffff0000u));
}

void main() {
  const uint t = gl_LocalInvocationIndex, tx = t % 16u, ty = t / 16u;
  const uint m0 = gl_WorkGroupID.x * BM, n0 = gl_WorkGroupID.y * BN;
  const uint M = p.M, N = p.N, cp = p.cp, cp4 = cp >> 2;
  const uint taps_hw = p.kh * p.kw, K = p.kt * taps_hw * cp;

  // The pixel this invocation gathers (tails clamped into the chunk: loaded, never stored).
  const uint am = t % uint(BM), bn = t % uint(BN);
  uint pf;
  int ph, pw;
  {
    uint m = min(m0 + am, M - 1u), ow = m % p.wo, r = m / p.wo;
    pf = r / p.rows;
    ph = int((p.oh0 + r % p.rows) * p.stride) - p.pad_top;
    pw = int((p.ow0 + ow) * p.stride) - p.pad_left;
  }
  const uint wrow = min(n0 + bn, N - 1u) * K;

  float acc[TM][TN];
  [[unroll]] for (int i = 0; i < TM; ++i)
    [[unroll]] for (int j = 0; j < TN; ++j) acc[i][j] = 0.0;

  for (uint k0 = 0u; k0 < K; k0 += uint(BK)) {
    [[unroll]] for (int s = 0; s < SA; ++s) {
      uint q = t / uint(BM) + uint(s * 256 / BM);  // which 4 of the 16 reduction elements
      if (q < 4u) {
        uint k = k0 + 4u * q;
        vec4 v = vec4(0.0);
        if (k < K) {
          uint tap = k / cp, c = k - tap * cp;
          uint a = tap / taps_hw, uv = tap - a * taps_hw, u = uv / p.kw, vv = uv - u * p.kw;
          int ih = ph + int(u), iw = pw + int(vv);
          bool inside = ih >= 0 && ih < int(p.in_h) && iw >= 0 && iw < int(p.in_w);
          uint pix = ((pf + a) * p.src_rows + uint(ih) / p.up - p.src_r0) * p.src_w + uint(iw) / p.up - p.src_c0;
          v = x[(inside ? pix * cp4 : p.zero_texel) + (c >> 2)];
        }
        As[4u * q][am] = v.x; As[4u * q + 1u][am] = v.y; As[4u * q + 2u][am] = v.z; As[4u * q + 3u][am] = v.w;
      }
    }
    [[unroll]] for (int s = 0; s < SB; ++s) {
      uint q = t / uint(BN) + uint(s * 256 / BN);
      if (q < 4u) {
        uint k = k0 + 4u * q;
        vec4 v = k < K ? w4(wrow + k) : vec4(0.0);
        Bs[4u * q][bn] = v.x; Bs[4u * q + 1u][bn] = v.y; Bs[4u * q + 2u][bn] = v.z; Bs[4u * q + 3u][bn] = v.w;
      }
    }
    barrier();
    [[unroll]] for (int kk = 0; kk < BK; ++kk) {
      float a[TM], b[TN];
      [[unroll]] for (int i = 0; i < TM; ++i) a[i] = As[kk][tx + 16u * uint(i)];
      [[unroll]] for (int j = 0; j < TN; ++j) b[j] = Bs[kk][ty + 16u * uint(j)];
      [[unroll]] for (int i = 0; i < TM; ++i)
        [[unroll]] for (int j = 0; j < TN; ++j) acc[i][j] = fma(a[i], b[j], acc[i][j]);
    }
    barrier();
  }

  // Epilogue as conv_gemm.comp's: bias with the first input-channel chunk, later chunks add into y.
  [[unroll]] for (int i = 0; i < TM; ++i) {
    uint m = m0 + tx + 16u * uint(i);
    if (m >= M) continue;
    uint ow = m % p.wo, r = m / p.wo;
    uint ybase = p.y_base + (r / p.rows) * p.ys_f + (r % p.rows) * p.ys_h + ow * p.ys_w;
    [[unroll]] for (int j = 0; j < TN; ++j) {
      uint n = n0 + ty + 16u * uint(j);
      if (n >= N) continue;
      float f = acc[i][j];
      if (p.accumulate != 0u) f = y[ybase + n * p.ys_c] + f;
      else if (p.has_bias != 0u) f += w_bias(p.n_base + n);
      y[ybase + n * p.ys_c] = f;
    }
  }
}
