#version 450
#extension GL_GOOGLE_include_directive : require
// nn/conv_coopmat, the convolution on tensor cores, and its fp32 twin nn/conv_coopmat_twin (TWIN,
// shaders/variants.cmake; no cooperative matrices: the tests' stand-in on devices without them).
// The implicit GEMM of conv_gemm.comp / conv_tiled.comp over the same repacked operands and push constants:
//   Y[m, n] = bias[n] + sum_k X[m, k] W[n, k],  m = output pixel of the chunk, n = output channel,
//   k = tap * CP + input channel (the packed weights are [Cout][K], K = taps * CP, CP % 8 == 0).
// The layout comes from the tuning table (DeviceTuning::conv_coopmat, coopmat, coopmat_lanes; checked against the
// device by tensor/coopmat_layout.cpp, which also requires the subgroup size at pipeline creation): SG_M x SG_N
// subgroups of LANES lanes, each multiplying FM x FN fragments of FRAG_M x FRAG_N x FRAG_K with fp32
// accumulators, so a workgroup computes BM pixels x BN channels. On the H200: 8 subgroups of 32 as 4 (pixels) x 2,
// 2 x 4 fragments of 16 x 16 x 16 each, BM = BN = 128; on lavapipe (8 lanes) the same arrangement of 8 x 8 x 8
// fragments, BM = BN = 64. Per BK reduction elements the workgroup gathers the input tile (4 channels of one
// tap per load; an invocation keeps its pixels for the whole loop: one pixel and several channel groups when
// there are at least BM invocations, else BM / WG pixels and every group) and the weight tile, rounds both to
// fp16 into shared memory (As [m][k], Bs [n][k], rows padded to BK + 8 halves), then each subgroup multiplies
// its part; with two stages (STAGES) the next step's gather is in flight during this step's products. Epilogue: fragment by fragment through a FRAG_M x FRAG_N fp32 staging area per subgroup
// (column-major: neighbouring lanes write neighbouring pixels), bias and y's layout as conv_gemm.comp.
// fp16 operands: |x| or |w| above 65504 becomes inf (the VAE's activations and weights stay far below), and
// each operand carries a relative rounding error of up to 2^-11; sums are fp32.
// The twin runs the same loads, the same fp16 rounding, the same staging and epilogue; only the product
// (fp32 FMA per lane on the values a fragment would hold, with LANES lanes emulated by the workgroup) differs.
#ifndef TWIN
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_shader_subgroup_basic : require
#endif
#extension GL_EXT_control_flow_attributes : require
layout(local_size_x_id = 9) in;  // WG = SG_M * SG_N * LANES

layout(constant_id = 0) const int WTYPE = 2;     // weight storage: 0 f32, 1 f16, 2 bf16
layout(constant_id = 1) const uint SG_M = 4;     // subgroups along the pixels
layout(constant_id = 2) const uint SG_N = 2;     // subgroups along the output channels
layout(constant_id = 3) const uint FM = 2;       // fragments per subgroup along the pixels
layout(constant_id = 4) const uint FN = 4;       // along the channels
layout(constant_id = 5) const uint BK = 32;      // reduction elements per step: a multiple of 8 and of FRAG_K
layout(constant_id = 6) const uint FRAG_M = 16;  // the device's fragment shape
layout(constant_id = 7) const uint FRAG_N = 16;
layout(constant_id = 8) const uint FRAG_K = 16;
layout(constant_id = 10) const uint LANES = 32;  // the subgroup size (required at pipeline creation; the twin emulates it)
// Shared-memory stages of the operand tiles (the host picks 2 where they fit): 2, the next step's operands are
// loaded into registers before this step's products and stored to the other stage after them, one barrier a
// step; 1, load, barrier, products, barrier.
layout(constant_id = 11) const uint STAGES = 1;
// The packed input chunk in fp16 (conv_pack_input.comp's OUT_F16): 4 channels per 8 bytes at the same indices,
// already the operand values (half the bytes every tap reads); else fp32, rounded here.
layout(constant_id = 12) const bool X_F16 = false;
layout(constant_id = 13) const int BTYPE = 2;  // bias storage (conv_bias.glsl): 0 f32, 1 f16, 2 bf16

const uint WG = gl_WorkGroupSize.x;
const uint WM = FM * FRAG_M, WN = FN * FRAG_N;   // one subgroup's part
const uint BM = SG_M * WM, BN = SG_N * WN, LD = BK + 8;  // LD: shared row stride in halves
const uint FRAG = FRAG_M * FRAG_N;
// The gather of a BM (or BN) x BK tile in groups of 4 reduction elements: invocation t takes rows t % BM + WG·p
// for p < PIX (PIX > 1 only when WG < BM) and groups t / BM + STEP·q for q < (BK / 4) / STEP (STEP > 1 only when
// WG > BM). The host checks that WG and BM (BN) divide one another and STEP divides BK / 4.
const uint PIX_A = (BM + WG - 1) / WG, STEP_A = (WG + BM - 1) / BM;
const uint PIX_B = (BN + WG - 1) / WG, STEP_B = (WG + BN - 1) / BN;

layout(std430, binding = 0) readonly buffer X { vec4 x[]; };  // packed input chunk + one zero pixel
layout(std430, binding = 0) readonly buffer XH { uvec2 xh[]; };  // X_F16: the same, 4 halves per element
vec4 x4(uint i) { return X_F16 ? vec4(unpackHalf2x16(xh[i].x), unpackHalf2x16(xh[i].y)) : x[i]; }
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
shared float16_t As[STAGES * BM * LD];
shared float16_t Bs[STAGES * BN * LD];
void put4(bool b, uint o, vec4 v) {  // elements o..o+3 (o even)
  if (b) {
    Bs[o] = float16_t(v.x); Bs[o + 1u] = float16_t(v.y); Bs[o + 2u] = float16_t(v.z); Bs[o + 3u] = float16_t(v.w);
  } else {
    As[o] = float16_t(v.x); As[o + 1u] = float16_t(v.y); As[o + 2u] = float16_t(v.z); As[o + 3u] = float16_t(v.w);
  }
}
#else
shared uint As[STAGES * BM * LD / 2];
shared uint Bs[STAGES * BN * LD / 2];
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
const uint EPL = FRAG / LANES;  // fragment elements per emulated lane (the host checks LANES divides FRAG)
float b_at(uint i) { return unpackHalf2x16(Bs[i >> 1])[i & 1u]; }
#endif
shared float Stage[SG_M * SG_N * FRAG];  // one fp32 fragment per subgroup, column-major

#include "conv_bias.glsl"

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

// The invocation's gather (set up once in main): the pixels and output channels it loads (tails clamped: loaded,
// never stored), and one step's operands between their loads and their shared stores.
const uint SA = BK / 4u / STEP_A, SB = BK / 4u / STEP_B;  // 4-element groups per pixel / channel and step
uint pf[PIX_A];
int ph[PIX_A], pw[PIX_A];
uint wrow[PIX_B];
vec4 ra[PIX_A * SA], rb[PIX_B * SB];

// The first texel (channels 0..3) of the input pixel that tap `tap` of the kernel reads for gathered pixel i: the
// packed chunk's pixel, or the zero pixel where the tap falls in the padding.
uint tap_texel(uint i, uint tap) {
  const uint taps_hw = p.kh * p.kw, at = tap / taps_hw, uv = tap - at * taps_hw, u = uv / p.kw, v = uv - u * p.kw;
  const int ih = ph[i] + int(u), iw = pw[i] + int(v);
  const bool inside = ih >= 0 && ih < int(p.in_h) && iw >= 0 && iw < int(p.in_w);
  const uint pix = ((pf[i] + at) * p.src_rows + uint(ih) / p.up - p.src_r0) * p.src_w + uint(iw) / p.up - p.src_c0;
  return inside ? pix * (p.cp >> 2) : p.zero_texel;
}

// Loads the operands of the step at reduction element k0 (of K) into ra, rb.
void load_step(uint k0, uint K) {
  const uint t = gl_LocalInvocationIndex, cp = p.cp;
  // Channels a multiple of BK (the VAE's 128, 256 and 512): each step reads BK channels of one tap, so the tap's
  // offsets and each pixel's source index are worked out once per step (uniform divisions) and a load is one
  // add; else (few or odd channels) each 4-channel group finds its own tap.
  if (cp % BK == 0u) {
    const uint tap = k0 / cp, c4 = (k0 - tap * cp) >> 2;
    [[unroll]] for (uint i = 0u; i < PIX_A; ++i) {
      const uint base = tap_texel(i, tap) + c4;
      // K is a multiple of BK here: every group is inside.
      [[unroll]] for (uint s = 0u; s < SA; ++s) ra[i * SA + s] = x4(base + t / BM + STEP_A * s);
    }
  } else {
    [[unroll]] for (uint i = 0u; i < PIX_A; ++i)
      [[unroll]] for (uint s = 0u; s < SA; ++s) {
        const uint k = k0 + 4u * (t / BM + STEP_A * s), tap = k / cp;  // reduction elements k..k+3 (one tap)
        ra[i * SA + s] = vec4(0.0);
        if (k < K) ra[i * SA + s] = x4(tap_texel(i, tap) + ((k - tap * cp) >> 2));
      }
  }
  [[unroll]] for (uint i = 0u; i < PIX_B; ++i)
    [[unroll]] for (uint s = 0u; s < SB; ++s) {
      const uint k = k0 + 4u * (t / BN + STEP_B * s);
      rb[i * SB + s] = k < K ? w4(wrow[i] + k) : vec4(0.0);
    }
}

// Stores ra, rb (fp16) into shared stage `stage`.
void store_step(uint stage) {
  const uint t = gl_LocalInvocationIndex;
  [[unroll]] for (uint i = 0u; i < PIX_A; ++i)
    [[unroll]] for (uint s = 0u; s < SA; ++s)
      put4(false, (stage * BM + t % BM + WG * i) * LD + 4u * (t / BM + STEP_A * s), ra[i * SA + s]);
  [[unroll]] for (uint i = 0u; i < PIX_B; ++i)
    [[unroll]] for (uint s = 0u; s < SB; ++s)
      put4(true, (stage * BN + t % BN + WG * i) * LD + 4u * (t / BN + STEP_B * s), rb[i * SB + s]);
}

void main() {
  const uint t = gl_LocalInvocationIndex;
#ifndef TWIN
  const uint sg = gl_SubgroupID, lane = gl_SubgroupInvocationID;
#else
  const uint sg = t / LANES, lane = t % LANES;
#endif
  const uint sm = sg % SG_M, sn = sg / SG_M;  // the subgroup's part: pixels sm*WM.., channels sn*WN..
  const uint m0 = gl_WorkGroupID.x * BM, n0 = gl_WorkGroupID.y * BN;
  const uint M = p.M, N = p.N, cp = p.cp;
  const uint taps_hw = p.kh * p.kw, K = p.kt * taps_hw * cp;

  [[unroll]] for (uint i = 0u; i < PIX_A; ++i) {
    uint m = min(m0 + t % BM + WG * i, M - 1u), ow = m % p.wo, r = m / p.wo;
    pf[i] = r / p.rows;
    ph[i] = int((p.oh0 + r % p.rows) * p.stride) - p.pad_top;
    pw[i] = int((p.ow0 + ow) * p.stride) - p.pad_left;
  }
  [[unroll]] for (uint i = 0u; i < PIX_B; ++i) wrow[i] = min(n0 + t % BN + WG * i, N - 1u) * K;

#ifndef TWIN
  coopmat<float, gl_ScopeSubgroup, FRAG_M, FRAG_N, gl_MatrixUseAccumulator> acc[FM][FN];
  [[unroll]] for (uint i = 0u; i < FM; ++i)
    [[unroll]] for (uint j = 0u; j < FN; ++j) acc[i][j] = coopmat<float, gl_ScopeSubgroup, FRAG_M, FRAG_N, gl_MatrixUseAccumulator>(0.0);
#else
  // What fragment (i, j) holds in this lane, as staged: element e = lane + LANES·r of the column-major
  // fragment, i.e. row e % FRAG_M, column e / FRAG_M (EPL = FRAG / LANES elements per lane).
  float acc[FM][FN][EPL];
  [[unroll]] for (uint i = 0u; i < FM; ++i)
    [[unroll]] for (uint j = 0u; j < FN; ++j)
      [[unroll]] for (uint r = 0u; r < EPL; ++r) acc[i][j][r] = 0.0;
#endif

  const uint steps = (K + BK - 1u) / BK;
  if (steps > 0u) {
    load_step(0u, K);
    store_step(0u);
  }
  barrier();
  for (uint step = 0u; step < steps; ++step) {
    const uint cur = STAGES == 2u ? step & 1u : 0u;
    const bool more = step + 1u < steps;
    if (STAGES == 2u && more) load_step((step + 1u) * BK, K);
    const uint a0 = cur * BM * LD, b0 = cur * BN * LD;
#ifndef TWIN
    [[unroll]] for (uint kk = 0u; kk < BK; kk += FRAG_K) {
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_M, FRAG_K, gl_MatrixUseA> fa[FM];
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_K, FRAG_N, gl_MatrixUseB> fb[FN];
      [[unroll]] for (uint i = 0u; i < FM; ++i)
        coopMatLoad(fa[i], As, a0 + (sm * WM + FRAG_M * i) * LD + kk, LD, gl_CooperativeMatrixLayoutRowMajor);
      // B[k][n] = Bs[n * LD + k]: column-major K x N.
      [[unroll]] for (uint j = 0u; j < FN; ++j)
        coopMatLoad(fb[j], Bs, b0 + (sn * WN + FRAG_N * j) * LD + kk, LD, gl_CooperativeMatrixLayoutColumnMajor);
      [[unroll]] for (uint i = 0u; i < FM; ++i)
        [[unroll]] for (uint j = 0u; j < FN; ++j) acc[i][j] = coopMatMulAdd(fa[i], fb[j], acc[i][j]);
    }
#else
    for (uint kk = 0u; kk < BK; ++kk)
      [[unroll]] for (uint r = 0u; r < EPL; ++r) {
        const uint e = lane + LANES * r, row = e % FRAG_M, col = e / FRAG_M;
        float a[FM], b[FN];
        [[unroll]] for (uint i = 0u; i < FM; ++i) a[i] = a_at(a0 + (sm * WM + FRAG_M * i + row) * LD + kk);
        [[unroll]] for (uint j = 0u; j < FN; ++j) b[j] = b_at(b0 + (sn * WN + FRAG_N * j + col) * LD + kk);
        [[unroll]] for (uint i = 0u; i < FM; ++i)
          [[unroll]] for (uint j = 0u; j < FN; ++j) acc[i][j][r] = fma(a[i], b[j], acc[i][j][r]);
      }
#endif
    if (STAGES == 2u) {
      if (more) store_step(cur ^ 1u);
      barrier();  // this stage read by all and the other written, before the next step swaps them
    } else {
      barrier();  // every subgroup is done with the stage before it is refilled
      if (more) {
        load_step((step + 1u) * BK, K);
        store_step(0u);
        barrier();
      }
    }
  }

  // Epilogue, one fragment at a time through the subgroup's staging area.
  [[unroll]] for (uint i = 0u; i < FM; ++i)
    [[unroll]] for (uint j = 0u; j < FN; ++j) {
#ifndef TWIN
      coopMatStore(acc[i][j], Stage, sg * FRAG, FRAG_M, gl_CooperativeMatrixLayoutColumnMajor);
      subgroupMemoryBarrierShared();
      subgroupBarrier();
      for (uint e = lane; e < FRAG; e += LANES)
        store(m0 + sm * WM + FRAG_M * i + e % FRAG_M, n0 + sn * WN + FRAG_N * j + e / FRAG_M, Stage[sg * FRAG + e]);
      subgroupBarrier();  // every lane has read the fragment before the next one overwrites it
#else
      [[unroll]] for (uint r = 0u; r < EPL; ++r) Stage[sg * FRAG + lane + LANES * r] = acc[i][j][r];
      barrier();  // (orders workgroup memory too)
      for (uint e = lane; e < FRAG; e += LANES)
        store(m0 + sm * WM + FRAG_M * i + e % FRAG_M, n0 + sn * WN + FRAG_N * j + e / FRAG_M, Stage[sg * FRAG + e]);
      barrier();
#endif
    }
}
