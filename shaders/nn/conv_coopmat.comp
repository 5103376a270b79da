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
// 16-byte gathers (the host sets it for an fp16 input chunk, channels a multiple of BK, 16-bit weights and kernels
// of at most 16 x 16 taps per frame: the VAE's convolutions on GPUs): each load is 8 channels (one uvec4), stored
// to shared memory as it is (fp16; bf16 weights converted), invocation t taking vector t % (BK / 8) of pixels
// t / (BK / 8) + (WG / (BK / 8))·j, so neighbouring lanes read one pixel's contiguous channels. Each pixel's
// source index and which of its taps fall inside the image are worked out once (gather_setup), so a load is a
// mask test and two adds: no division in the loop.
layout(constant_id = 14) const bool VEC8 = false;

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
layout(std430, binding = 0) readonly buffer XV8 { uvec4 xv8[]; };  // VEC8: the fp16 chunk, 8 channels per element
layout(std430, binding = 1) readonly buffer W { uint w[]; };  // packed weights, the stored dtype
layout(std430, binding = 1) readonly buffer WV8 { uvec4 wv8[]; };  // VEC8: 16-bit weights, 8 per element
layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };
layout(std430, binding = 3) buffer Y { float y[]; };

#include "conv_push.glsl"
#include "f16.glsl"

// The operand tiles in shared memory, fp16: float16_t for the tensor cores; in the twin the same fp16
// values as bits, two per uint (fp32 tiles would need 40 KiB, over the 32 KiB lavapipe offers).
// bf16 pair (one word) -> two floats: a bf16 is the high half of its f32.
vec2 bf16x2(uint u) { return vec2(uintBitsToFloat(u << 16), uintBitsToFloat(u & 0xffff0000u)); }

#ifndef TWIN
// In 8-byte units (f16vec4), so that four staged values are one store; coopMatLoad counts in the same units.
shared f16vec4 As[STAGES * BM * LD / 4];
shared f16vec4 Bs[STAGES * BN * LD / 4];
void put4(bool b, uint o, vec4 v) {  // elements o..o+3 (o a multiple of 4)
  if (b) {
    Bs[o >> 2] = f16vec4(v);
  } else {
    As[o >> 2] = f16vec4(v);
  }
}
// Eight 16-bit values (one uvec4) at element o (a multiple of 8): fp16 as they are, bf16 (bf16 = true) rounded to fp16.
void put8(bool b, uint o, uvec4 u, bool bf16) {
  const f16vec4 lo = bf16 ? f16vec4(vec4(bf16x2(u.x), bf16x2(u.y))) : f16vec4(unpackFloat2x16(u.x), unpackFloat2x16(u.y));
  const f16vec4 hi = bf16 ? f16vec4(vec4(bf16x2(u.z), bf16x2(u.w))) : f16vec4(unpackFloat2x16(u.z), unpackFloat2x16(u.w));
  if (b) {
    Bs[o >> 2] = lo; Bs[(o >> 2) + 1u] = hi;
  } else {
    As[o >> 2] = lo; As[(o >> 2) + 1u] = hi;
  }
}
#else
shared uint As[STAGES * BM * LD / 2];
shared uint Bs[STAGES * BN * LD / 2];
// f16_value (f16.glsl) rounds on the bits, so that the packing below is exact whatever rounding packHalf2x16 uses.
void put4(bool b, uint o, vec4 v) {
  uint lo = packHalf2x16(vec2(f16_value(v.x), f16_value(v.y))), hi = packHalf2x16(vec2(f16_value(v.z), f16_value(v.w)));
  if (b) {
    Bs[o >> 1] = lo; Bs[(o >> 1) + 1u] = hi;
  } else {
    As[o >> 1] = lo; As[(o >> 1) + 1u] = hi;
  }
}
void put8(bool b, uint o, uvec4 u, bool bf16) {
  if (bf16) {
    put4(b, o, vec4(bf16x2(u.x), bf16x2(u.y)));
    put4(b, o + 4u, vec4(bf16x2(u.z), bf16x2(u.w)));
  } else if (b) {  // fp16 pairs: already the operand bits
    Bs[o >> 1] = u.x; Bs[(o >> 1) + 1u] = u.y; Bs[(o >> 1) + 2u] = u.z; Bs[(o >> 1) + 3u] = u.w;
  } else {
    As[o >> 1] = u.x; As[(o >> 1) + 1u] = u.y; As[(o >> 1) + 2u] = u.z; As[(o >> 1) + 3u] = u.w;
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
  return vec4(bf16x2(a), bf16x2(b));
}

// y's element of output pixel m (< M), channel 0 of the group.
uint pixel_offset(uint m) {
  const uint ow = m % p.wo, r = m / p.wo;
  return p.y_base + (r / p.rows) * p.ys_f + (r % p.rows) * p.ys_h + ow * p.ys_w;
}
// Output channel n of the pixel at y element yi0, with the bias (first input-channel chunk) or added to y (later ones).
void store_at(uint yi0, uint n, float f) {
  if (n >= p.N) return;
  const uint yi = yi0 + n * p.ys_c;
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
// VEC8's gather: vector t % XV of pixels t / XV + RV·j (j < VPA) and of weight rows t / XV + RV·j (j < VPB); the
// host checks that RV divides BM and BN.
const uint XV = BK / 8u, RV = WG / XV, VPA = BM / RV, VPB = BN / RV;
int vbase[VEC8 ? VPA : 1];   // the packed pixel that tap (0, 0, 0) reads, were it inside (may lie outside the chunk)
uint vmask[VEC8 ? VPA : 1];  // bit u: the tap row u is inside the image; bit 16 + v: tap column v
uint vpar[VEC8 ? VPA : 1];   // upsampling: bit 0 the first tap row's parity, bit 1 the first tap column's
uint vwrow[VEC8 ? VPB : 1];  // first weight of the row
uvec4 va[VEC8 ? VPA : 1], vb[VEC8 ? VPB : 1];
// The tap the next load_step reads (steps are loaded in order, from 0): its first channel / 8, kernel row u, column
// v, frame.
uvec4 vtap = uvec4(0u);

// VEC8: each gathered pixel's source index and in-image taps (the divisions happen here, once).
void gather_setup(uint m0, uint n0, uint K) {
  const uint t = gl_LocalInvocationIndex, sh = p.up == 2u ? 1u : 0u, odd = p.up - 1u;
  [[unroll]] for (uint j = 0u; j < VPA; ++j) {
    const uint m = min(m0 + t / XV + RV * j, p.M - 1u), ow = m % p.wo, r = m / p.wo;
    const int ih0 = int((p.oh0 + r % p.rows) * p.stride) - p.pad_top, iw0 = int((p.ow0 + ow) * p.stride) - p.pad_left;
    uint mask = 0u;
    for (uint u = 0u; u < p.kh; ++u) mask |= (ih0 + int(u) >= 0 && ih0 + int(u) < int(p.in_h)) ? 1u << u : 0u;
    for (uint v = 0u; v < p.kw; ++v) mask |= (iw0 + int(v) >= 0 && iw0 + int(v) < int(p.in_w)) ? 1u << (16u + v) : 0u;
    vmask[j] = mask;
    vpar[j] = (uint(ih0) & odd) | ((uint(iw0) & odd) << 1);
    vbase[j] = (int(r / p.rows * p.src_rows) + (ih0 >> sh) - int(p.src_r0)) * int(p.src_w) + (iw0 >> sh) - int(p.src_c0);
  }
  [[unroll]] for (uint j = 0u; j < VPB; ++j) vwrow[j] = min(n0 + t / XV + RV * j, p.N - 1u) * K;
}

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
  if (VEC8) {  // one tap, BK channels (vtap): a mask test and two adds a load
    const uint c8 = vtap.x, u = vtap.y, v = vtap.z, sh = p.up == 2u ? 1u : 0u, xc = t % XV;
    const int frame_rows = int(vtap.w * p.src_rows);
    [[unroll]] for (uint j = 0u; j < VPA; ++j) {
      const uint mk = vmask[j], par = vpar[j];
      const bool inside = ((mk >> u) & (mk >> (16u + v)) & 1u) != 0u;
      const int pix = vbase[j] + (frame_rows + int(((par & 1u) + u) >> sh)) * int(p.src_w) + int(((par >> 1) + v) >> sh);
      va[j] = inside ? xv8[uint(pix) * (cp >> 3) + c8 + xc] : uvec4(0u);  // zeros: the tap is in the padding
    }
    [[unroll]] for (uint j = 0u; j < VPB; ++j) vb[j] = wv8[((vwrow[j] + k0) >> 3) + xc];
    // The next step's tap: BK channels on, then the next column, row, frame of the kernel (no division).
    vtap.x += BK / 8u;
    if (vtap.x == cp >> 3) {
      vtap.x = 0u;
      if (++vtap.z == p.kw) {
        vtap.z = 0u;
        if (++vtap.y == p.kh) vtap.y = 0u, ++vtap.w;
      }
    }
    return;
  }
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
  if (VEC8) {
    const uint r = t / XV, xc = t % XV;
    [[unroll]] for (uint j = 0u; j < VPA; ++j) put8(false, (stage * BM + r + RV * j) * LD + 8u * xc, va[j], false);
    [[unroll]] for (uint j = 0u; j < VPB; ++j) put8(true, (stage * BN + r + RV * j) * LD + 8u * xc, vb[j], WTYPE == 2);
    return;
  }
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
  if (VEC8) gather_setup(m0, n0, K);

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
        coopMatLoad(fa[i], As, (a0 + (sm * WM + FRAG_M * i) * LD + kk) / 4u, LD / 4u, gl_CooperativeMatrixLayoutRowMajor);
      // B[k][n] = Bs[n * LD + k]: column-major K x N.
      [[unroll]] for (uint j = 0u; j < FN; ++j)
        coopMatLoad(fb[j], Bs, (b0 + (sn * WN + FRAG_N * j) * LD + kk) / 4u, LD / 4u, gl_CooperativeMatrixLayoutColumnMajor);
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

  // Epilogue, one fragment at a time through the subgroup's staging area. Lane l handles elements l + LANES·r of
  // the column-major fragment: when LANES is a multiple of FRAG_M these are one pixel (row l % FRAG_M), whose y
  // offset is worked out once per fragment row.
  const bool LANE_PIXEL = LANES % FRAG_M == 0u;
  [[unroll]] for (uint i = 0u; i < FM; ++i) {
    const uint mrow = m0 + sm * WM + FRAG_M * i, mlane = mrow + lane % FRAG_M;
    const uint yi_lane = LANE_PIXEL && mlane < M ? pixel_offset(mlane) : 0u;
    [[unroll]] for (uint j = 0u; j < FN; ++j) {
#ifndef TWIN
      coopMatStore(acc[i][j], Stage, sg * FRAG, FRAG_M, gl_CooperativeMatrixLayoutColumnMajor);
      subgroupMemoryBarrierShared();
      subgroupBarrier();
#else
      [[unroll]] for (uint r = 0u; r < EPL; ++r) Stage[sg * FRAG + lane + LANES * r] = acc[i][j][r];
      barrier();  // (orders workgroup memory too)
#endif
      const uint nb = n0 + sn * WN + FRAG_N * j;
      for (uint e = lane; e < FRAG; e += LANES) {
        const uint m = mrow + e % FRAG_M;
        if (m < M) store_at(LANE_PIXEL ? yi_lane : pixel_offset(m), nb + e / FRAG_M, Stage[sg * FRAG + e]);
      }
#ifndef TWIN
      subgroupBarrier();  // every lane has read the fragment before the next one overwrites it
#else
      barrier();
#endif
    }
  }
}
