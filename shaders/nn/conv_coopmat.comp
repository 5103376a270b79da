#version 450
#extension GL_GOOGLE_include_directive : require
// nn/conv_coopmat, the convolution on tensor cores, and its fp32 twin nn/conv_coopmat_twin (TWIN,
// shaders/variants.cmake; no cooperative matrices: the tests' stand-in on devices without them).
// The implicit GEMM of conv_gemm.comp / conv_tiled.comp over the same repacked operands and push constants:
//   Y[m, n] = bias[n] + sum_k X[m, k] W[n, k],  m = output pixel of the chunk, n = output channel,
//   k = tap * CP + input channel (the packed weights are [Cout][K], K = taps * CP, CP % 8 == 0).
// A workgroup of 256 invocations computes BM = 128 pixels x BN = 128 channels; per BK = 32 reduction
// elements it gathers the input tile (each invocation keeps one pixel for the whole loop, 4 vec4 loads) and
// the weight tile, rounds both to fp16 into shared memory (As [m][k], Bs [n][k], rows padded to 40 halves),
// then each of the 8 subgroups (32 lanes) multiplies its 32 x 64 part as 2 x 4 fragments of 16 x 16 x 16
// with fp32 accumulators. Epilogue: fragment by fragment through a 16 x 16 fp32 staging area per subgroup
// (column-major: neighbouring lanes write neighbouring pixels), bias and y's layout as conv_gemm.comp.
// fp16 operands: |x| or |w| above 65504 becomes inf (the VAE's activations and weights stay far below), and
// each operand carries a relative rounding error of up to 2^-11; sums are fp32.
// The twin runs the same loads, the same fp16 rounding, the same staging and epilogue; only the product
// (fp32 FMA per lane on the values a fragment would hold) differs. Needs 8 subgroups of 32 lanes
// (kernel_tuning.cpp selects coopmat convolutions only on such devices).
#ifndef TWIN
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_shader_subgroup_basic : require
#endif
#extension GL_EXT_control_flow_attributes : require
layout(local_size_x = 256) in;

layout(constant_id = 0) const int WTYPE = 2;  // weight storage: 0 f32, 1 f16, 2 bf16

const int BM = 128, BN = 128, BK = 32, LD = BK + 8;  // LD: shared row stride in halves (80 bytes)
const int WM = 32, WN = 64;                          // one subgroup's part: 2 x 4 fragments

layout(std430, binding = 0) readonly buffer X { vec4 x[]; };  // packed input chunk + one zero pixel
layout(std430, binding = 1) readonly buffer W { uint w[]; };  // packed weights, the stored dtype
layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };
layout(std430, binding = 3) buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint M, N, cp, kt, kh, kw, stride, up, wo, rows, oh0;
  int pad_top, pad_left;
  uint in_h, in_w, src_r0, src_rows, src_w, zero_texel, y_base;
  uint ys_f, ys_h, ys_w, ys_c, has_bias, n_base, accumulate, ow0, src_c0;
} p;

// The operand tiles in shared memory, fp16: float16_t for the tensor cores; in the twin the same fp16
// values as bits, two per uint (fp32 tiles would need 40 KiB, over the 32 KiB lavapipe offers).
#ifndef TWIN
shared float16_t As[BM * LD];
shared float16_t Bs[BN * LD];
void put4(bool b, uint o, vec4 v) {  // elements o..o+3 (o even)
  if (b) {
    Bs[o] = float16_t(v.x); Bs[o + 1u] = float16_t(v.y); Bs[o + 2u] = float16_t(v.z); Bs[o + 3u] = float16_t(v.w);
  } else {
    As[o] = float16_t(v.x); As[o + 1u] = float16_t(v.y); As[o + 2u] = float16_t(v.z); As[o + 3u] = float16_t(v.w);
  }
}
#else
shared uint As[BM * LD / 2];
shared uint Bs[BN * LD / 2];
// The value an fp16 operand holds: round to nearest even (as float16_t() converts), on the bits, so that
// the packing below is exact whatever rounding packHalf2x16 uses. Below 2^-14 fp16 steps by 2^-24
// (subnormals); above 65504 it is inf.
float f16_value(float v) {
  if (abs(v) < 6.103515625e-05) return roundEven(v * 16777216.0) * 5.9604644775390625e-08;
  uint b = floatBitsToUint(v);
  b = (b + 0xfffu + ((b >> 13) & 1u)) & ~0x1fffu;
  float r = uintBitsToFloat(b);
  return abs(r) > 65504.0 ? uintBitsToFloat((b & 0x80000000u) | 0x7f800000u) : r;
}
void put4(bool b, uint o, vec4 v) {
  uint lo = packHalf2x16(vec2(f16_value(v.x), f16_value(v.y))), hi = packHalf2x16(vec2(f16_value(v.z), f16_value(v.w)));
  if (b) {
    Bs[o >> 1] = lo; Bs[(o >> 1) + 1u] = hi;
  } else {
    As[o >> 1] = lo; As[(o >> 1) + 1u] = hi;
  }
}
float a_at(uint i) { return unpackHalf2x16(As[i >> 1])[i & 1u]; }
float b_at(uint i) { return unpackHalf2x16(Bs[i >> 1])[i & 1u]; }
#endif
shared float Stage[8 * 256];  // one 16 x 16 fp32 fragment per subgroup, column-major

float w_bias(uint n) {
  if (WTYPE == 0) return uintBitsToFloat(bias[n]);
  uint u = bias[n >> 1], bits = (n & 1u) == 0u ? (u & 0xffffu) : (u >> 16);
  return WTYPE == 1 ? unpackHalf2x16(bits).x : uintBitsToFloat(bits << 16);
}

vec4 w4(uint e) {  // four consecutive packed weights from element e (a multiple of 4)
  if (WTYPE == 0) return vec4(uintBitsToFloat(w[e]), uintBitsToFloat(w[e + 1u]), uintBitsToFloat(w[e + 2u]), uintBitsToFloat(w[e + 3u]));
  uint a = w[e >> 1], b = w[(e >> 1) + 1u];
  if (WTYPE == 1) return vec4(unpackHalf2x16(a), unpackHalf2x16(b));
  return vec4(uintBitsToFloat(a << 16), uintBitsToFloat(a & 0xffff0000u), uintBitsToFloat(b << 16), uintBitsToFloat(b & 0xffff0000u));
}

// Output element (m, n) of the tile, with the bias (first input-channel chunk) or added to y (later ones).
void store(uint m, uint n, float f) {
  if (m >= p.M || n >= p.N) return;
  uint ow = m % p.wo, r = m / p.wo;
  uint yi = p.y_base + (r / p.rows) * p.ys_f + (r % p.rows) * p.ys_h + ow * p.ys_w + n * p.ys_c;
  if (p.accumulate != 0u) f = y[yi] + f;
  else if (p.has_bias != 0u) f += w_bias(p.n_base + n);
  y[yi] = f;
}

void main() {
  const uint t = gl_LocalInvocationIndex;
#ifndef TWIN
  const uint sg = gl_SubgroupID, lane = gl_SubgroupInvocationID;
#else
  const uint sg = t / 32u, lane = t % 32u;
#endif
  const uint sm = sg % 4u, sn = sg / 4u;  // the subgroup's part: pixels sm*32.., channels sn*64..
  const uint m0 = gl_WorkGroupID.x * BM, n0 = gl_WorkGroupID.y * BN;
  const uint M = p.M, N = p.N, cp = p.cp, cp4 = cp >> 2;
  const uint taps_hw = p.kh * p.kw, K = p.kt * taps_hw * cp;

  // The pixel and the output channel this invocation gathers (tails clamped: loaded, never stored).
  const uint ld = t % 128u;
  uint pf;
  int ph, pw;
  {
    uint m = min(m0 + ld, M - 1u), ow = m % p.wo, r = m / p.wo;
    pf = r / p.rows;
    ph = int((p.oh0 + r % p.rows) * p.stride) - p.pad_top;
    pw = int((p.ow0 + ow) * p.stride) - p.pad_left;
  }
  const uint wrow = min(n0 + ld, N - 1u) * K;

#ifndef TWIN
  coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator> acc[2][4];
  [[unroll]] for (int i = 0; i < 2; ++i)
    [[unroll]] for (int j = 0; j < 4; ++j) acc[i][j] = coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator>(0.0);
#else
  // What fragment (i, j) holds in this lane, as staged: element e = lane + 32r of the column-major
  // fragment, i.e. row lane % 16, column lane / 16 + 2r.
  float acc[2][4][8];
  [[unroll]] for (int i = 0; i < 2; ++i)
    [[unroll]] for (int j = 0; j < 4; ++j)
      [[unroll]] for (int r = 0; r < 8; ++r) acc[i][j][r] = 0.0;
#endif

  for (uint k0 = 0u; k0 < K; k0 += uint(BK)) {
    [[unroll]] for (uint s = 0u; s < 4u; ++s) {
      const uint q = t / 128u + 2u * s, k = k0 + 4u * q;  // reduction elements k..k+3 (one tap)
      vec4 a = vec4(0.0), b = vec4(0.0);
      if (k < K) {
        uint tap = k / cp, c = k - tap * cp;
        uint at = tap / taps_hw, uv = tap - at * taps_hw, u = uv / p.kw, v = uv - u * p.kw;
        int ih = ph + int(u), iw = pw + int(v);
        bool inside = ih >= 0 && ih < int(p.in_h) && iw >= 0 && iw < int(p.in_w);
        uint pix = ((pf + at) * p.src_rows + uint(ih) / p.up - p.src_r0) * p.src_w + uint(iw) / p.up - p.src_c0;
        a = x[(inside ? pix * cp4 : p.zero_texel) + (c >> 2)];
        b = w4(wrow + k);
      }
      const uint o = ld * uint(LD) + 4u * q;
      put4(false, o, a);
      put4(true, o, b);
    }
    barrier();
#ifndef TWIN
    [[unroll]] for (uint kk = 0u; kk < uint(BK); kk += 16u) {
      coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseA> fa[2];
      coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseB> fb[4];
      [[unroll]] for (uint i = 0u; i < 2u; ++i)
        coopMatLoad(fa[i], As, (sm * uint(WM) + 16u * i) * uint(LD) + kk, uint(LD), gl_CooperativeMatrixLayoutRowMajor);
      // B[k][n] = Bs[n * LD + k]: column-major K x N.
      [[unroll]] for (uint j = 0u; j < 4u; ++j)
        coopMatLoad(fb[j], Bs, (sn * uint(WN) + 16u * j) * uint(LD) + kk, uint(LD), gl_CooperativeMatrixLayoutColumnMajor);
      [[unroll]] for (uint i = 0u; i < 2u; ++i)
        [[unroll]] for (uint j = 0u; j < 4u; ++j) acc[i][j] = coopMatMulAdd(fa[i], fb[j], acc[i][j]);
    }
#else
    const uint row = lane % 16u, col = lane / 16u;
    for (uint kk = 0u; kk < uint(BK); ++kk) {
      float a[2], b[4][8];
      [[unroll]] for (uint i = 0u; i < 2u; ++i) a[i] = a_at((sm * uint(WM) + 16u * i + row) * uint(LD) + kk);
      [[unroll]] for (uint j = 0u; j < 4u; ++j)
        [[unroll]] for (uint r = 0u; r < 8u; ++r) b[j][r] = b_at((sn * uint(WN) + 16u * j + col + 2u * r) * uint(LD) + kk);
      [[unroll]] for (uint i = 0u; i < 2u; ++i)
        [[unroll]] for (uint j = 0u; j < 4u; ++j)
          [[unroll]] for (uint r = 0u; r < 8u; ++r) acc[i][j][r] = fma(a[i], b[j][r], acc[i][j][r]);
    }
#endif
    barrier();
  }

  // Epilogue, one fragment at a time through the subgroup's staging area.
  [[unroll]] for (uint i = 0u; i < 2u; ++i)
    [[unroll]] for (uint j = 0u; j < 4u; ++j) {
#ifndef TWIN
      coopMatStore(acc[i][j], Stage, sg * 256u, 16u, gl_CooperativeMatrixLayoutColumnMajor);
      subgroupMemoryBarrierShared();
      subgroupBarrier();
      for (uint e = lane; e < 256u; e += gl_SubgroupSize)
        store(m0 + sm * uint(WM) + 16u * i + e % 16u, n0 + sn * uint(WN) + 16u * j + e / 16u, Stage[sg * 256u + e]);
      subgroupBarrier();  // every lane has read the fragment before the next one overwrites it
#else
      [[unroll]] for (uint r = 0u; r < 8u; ++r) Stage[sg * 256u + lane + 32u * r] = acc[i][j][r];
      barrier();  // (orders workgroup memory too)
      for (uint e = lane; e < 256u; e += 32u)
        store(m0 + sm * uint(WM) + 16u * i + e % 16u, n0 + sn * uint(WN) + 16u * j + e / 16u, Stage[sg * 256u + e]);
      barrier();
#endif
    }
}
