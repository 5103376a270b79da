#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_cooperative_matrix : require
// Linear layer Y = epilogue(X·Wᵀ), the "coopmat" family (tensor cores through VK_KHR_cooperative_matrix).
// Its fp32 twin, tested on lavapipe, is linear_tiled.comp: same element loads (zero-filled outside M/N/K),
// same epilogue (linear_storage_io.glsl); only the tile product differs.
//
// The layout comes from the tuning table (DeviceTuning::linear_coopmat, coopmat, coopmat_lanes; checked
// against the device by tensor/coopmat_layout.cpp, which also requires the subgroup size at pipeline
// creation): SG_M x SG_N subgroups, each owning FM x FN fp32 accumulator fragments of FRAG_M x FRAG_N, so a
// workgroup computes a BM x BN tile of Y. On the H200: 8 subgroups of 32 as 2 x 4, 4 x 2 fragments of
// 16 x 16 x 16 each (64 x 32 outputs), BM = BN = 128; on lavapipe (8 lanes, 32 KiB) the same arrangement of
// 8 x 8 x 8 fragments, BM = BN = 64. Per K step of BK values, X[BM x BK] (f32 -> fp16, or fp16 as stored) and W[BN x BK]
// (f32/f16/bf16 -> fp16) are staged in shared memory, double-buffered: the next step's global loads are
// issued into registers before this step's MMAs and stored to the other buffer after them, so one barrier per
// step suffices. Two load paths (VEC): 16-byte vectors where K, strides and offsets allow (the models' shapes),
// else one guarded element per load (any size and offset). Tiles are visited in bands of GROUP_M tile rows.
// fp16 operands: |x| > 65504 becomes inf (callers that may exceed this set
// LinearEpilogue::fp16_operands_ok = false and get the tiled kernel); products accumulate in fp32.
// Epilogue: each subgroup stores one accumulator fragment at a time to its own FRAG_M x FRAG_N f32 staging
// block (row-major; column-major for the convolution, whose y is channel-planar) and its lanes apply the epilogue to
// those outputs with bounds checks.
// Shared memory: 2 x (BM + BN) x (BK + 8) halves + one fragment per subgroup (48 KiB on the H200).
// Variant nn/conv_shifted_coopmat (CONV_SHIFTED, conv_shifted_io.glsl): a stride-1 convolution as this GEMM, X the
// input repacked channels-last fp16 on its zero-padded grid and W the weights packed at load ([Cout][tap][CP]);
// each step's X rows are shifted by its tap's offset on the grid, and the epilogue maps grid rows to output pixels.
#ifdef CONV_SHIFTED
#include "conv_shifted_io.glsl"
#else
#include "linear_storage_io.glsl"
uint x_step_shift(uint k0) { return 0u; }
#endif
#include "gemm_tile_order.glsl"

layout(local_size_x_id = 9) in;                 // WG = SG_M * SG_N * the subgroup size
layout(constant_id = 0) const uint SG_M = 2;    // subgroups along M
layout(constant_id = 1) const uint SG_N = 4;    // subgroups along N
layout(constant_id = 3) const uint BK = 32;     // K per step: a multiple of 8 and of FRAG_K; WG a multiple of it
layout(constant_id = 4) const uint FRAG_K = 16; // the device's fragment shape, FRAG_M x FRAG_N x FRAG_K
layout(constant_id = 5) const uint FM = 4;      // fragments per subgroup along M
layout(constant_id = 6) const uint FN = 2;      // fragments per subgroup along N
layout(constant_id = 7) const uint FRAG_M = 16;
layout(constant_id = 8) const uint FRAG_N = 16;
// 16-byte loads (the host sets it only where K, every X/W stride and offset are multiples of 8 elements and WG
// a multiple of BK / 4): f32 X as vec4, f16 X and 16-bit W as uvec4 of 8 values (f32 W as vec4); one bounds
// test per vector.
layout(constant_id = 10) const bool VEC = false;
// Workgroup order (gemm_tile_order.glsl): bands of GROUP_M tile rows (1: row by row, the grid's own order).
layout(constant_id = 11) const uint GROUP_M = 1;
// Ablations for measurements only (DeviceTuning::linear_coopmat_ablation; the results are wrong): 1 the 16-byte
// path loads no operand from memory (each staged vector is a constant of its row; stores, barriers and MMAs
// stay), 2 no MMA (the feed alone). 0: the kernel.
layout(constant_id = 12) const uint ABLATE = 0;
// Y stored f16 (the next GEMM's X: the FFN's GELU output): each lane writes a pair of neighbouring outputs as one
// word (the host requires N, Y's strides and offset even and no residual, so a pair never straddles a row).
layout(constant_id = 14) const bool Y_F16 = false;
#ifndef CONV_SHIFTED
layout(std430, binding = 2) writeonly buffer Yh { uint yh[]; };
#endif

// 16-byte views of the X and W bindings (linear_storage_io.glsl declares their element views).
layout(std430, binding = 0) readonly buffer Xv { vec4 xv[]; };
layout(std430, binding = 0) readonly buffer Xhv { uvec4 xhv[]; };
layout(std430, binding = 1) readonly buffer Wv { uvec4 wv[]; };

const uint WG = gl_WorkGroupSize.x;
const uint BM = SG_M * FM * FRAG_M, BN = SG_N * FN * FRAG_N;
const uint LDS = BK + 8;        // shared row stride in halves: a multiple of 8 (16 bytes) for coopMatLoad
const uint LDS4 = LDS / 4;      // the same in the arrays' f16vec4 units
const uint ROWS = WG / BK;      // scalar staging: rows per pass (invocation t: column t % BK, row t / BK)
const uint PER_X = BM / ROWS, PER_W = BN / ROWS;  // passes per operand and step (16 each on the H200)
// Vector staging: X rows are BK / EX vectors of EX values (4 floats or 8 halves), W rows BK / EW; RX / RW rows
// per pass.
const uint EW = WTYPE == 0 ? 4 : 8, EX = XTYPE == 0 ? 4 : 8;
const uint XV = BK / EX, WVN = BK / EW;
const uint RX = WG / XV, RW = WG / WVN;
const uint VPX = (BM + RX - 1) / RX, VPW = (BN + RW - 1) / RW;
const uint FRAG = FRAG_M * FRAG_N;

shared f16vec4 sx[2 * BM * LDS4];  // [stage][row][k], fp16; 8-byte units so a staged vector is one store
shared f16vec4 sw[2 * BN * LDS4];
shared float stage[SG_M * SG_N * FRAG];

// One vector of X's row m from value k (k a multiple of EX below K or past it): 4 floats, or 8 halves as raw
// words; zeros outside the matrix.
uvec4 load_x4(uint b, uint m, uint k) {
  if (ABLATE == 1) return XTYPE == 0 ? floatBitsToUint(vec4(float(m & 7u) * 0.125)) : uvec4(0x30003000u ^ (m & 7u));
  if (m >= p.M || k >= p.K) return uvec4(0u);
  const uint e = p.x_off + b * p.x_bs + m * p.ldx + k + x_shift;
  return XTYPE == 0 ? floatBitsToUint(xv[e / 4]) : xhv[e / 8];
}

// Stores an X vector as fp16 at f16vec4 index i (EX values: i, and i + 1 for 8 halves).
void store_x4(uint i, uvec4 u) {
  if (XTYPE == 0) {
    sx[i] = f16vec4(uintBitsToFloat(u));
  } else {
    sx[i] = f16vec4(unpackFloat2x16(u.x), unpackFloat2x16(u.y));
    sx[i + 1] = f16vec4(unpackFloat2x16(u.z), unpackFloat2x16(u.w));
  }
}

// One vector of W's row n from value k: EW values (8 halves or 4 floats) as raw words, zeros outside.
uvec4 load_w4(uint b, uint n, uint k) {
  if (ABLATE == 1) return uvec4(0x3c003c00u ^ (n & 7u));  // fp16 pairs near 1.0 (f32 W: tiny values)
  if (n >= p.N || k >= p.K) return uvec4(0u);
  return wv[(p.w_off + b * p.w_bs + n * p.ldw + k) / EW];
}

// bf16 pair (one word) -> two floats: a bf16 is the high half of its f32.
vec2 bf16x2(uint u) { return vec2(uintBitsToFloat(u << 16), uintBitsToFloat(u & 0xffff0000u)); }

// Stores a W vector as fp16 at f16vec4 index i (8 values: i and i + 1).
void store_w4(uint i, uvec4 u) {
  if (WTYPE == 0) {
    sw[i] = f16vec4(uintBitsToFloat(u));
  } else if (WTYPE == 1) {
    sw[i] = f16vec4(unpackFloat2x16(u.x), unpackFloat2x16(u.y));
    sw[i + 1] = f16vec4(unpackFloat2x16(u.z), unpackFloat2x16(u.w));
  } else {
    sw[i] = f16vec4(vec4(bf16x2(u.x), bf16x2(u.y)));
    sw[i + 1] = f16vec4(vec4(bf16x2(u.z), bf16x2(u.w)));
  }
}

// The workgroup's tile (set in main) and one step's operands between their loads and their shared stores.
uint tb, tm0, tn0;  // batch item, first row, first column
float rx[VEC ? 1 : PER_X], rw[VEC ? 1 : PER_W];
uvec4 vx[VEC ? VPX : 1];
uvec4 vw[VEC ? VPW : 1];

// Loads the operands of the step at K value k0 into the registers above. Scalar map: invocation t loads
// k = t % BK of rows t / BK + ROWS·j (BK consecutive values per row); vector map: X vector t % XV of rows
// t / XV + RX·j, W vector t % WVN of rows t / WVN + RW·j.
void load_step(uint k0) {
  const uint t = gl_LocalInvocationIndex;
  x_shift = x_step_shift(k0);
  if (VEC) {
    const uint xc = t % XV, xr = t / XV, wc = t % WVN, wr = t / WVN;
    [[unroll]] for (uint j = 0; j < VPX; ++j) vx[j] = load_x4(tb, tm0 + xr + RX * j, k0 + xc * EX);
    [[unroll]] for (uint j = 0; j < VPW; ++j) vw[j] = load_w4(tb, tn0 + wr + RW * j, k0 + wc * EW);
  } else {
    const uint lk = t % BK, lr = t / BK;
    [[unroll]] for (uint j = 0; j < PER_X; ++j) rx[j] = load_x(tb, tm0 + lr + ROWS * j, k0 + lk);
    [[unroll]] for (uint j = 0; j < PER_W; ++j) rw[j] = load_w(tb, tn0 + lr + ROWS * j, k0 + lk);
  }
}

// Stores the registers (fp16) into shared stage `stage`.
void store_step(uint stage) {
  const uint t = gl_LocalInvocationIndex;
  if (VEC) {
    const uint xc = t % XV, xr = t / XV, wc = t % WVN, wr = t / WVN;
    [[unroll]] for (uint j = 0; j < VPX; ++j)
      if (xr + RX * j < BM) store_x4((stage * BM + xr + RX * j) * LDS4 + xc * (EX / 4), vx[j]);
    [[unroll]] for (uint j = 0; j < VPW; ++j)
      if (wr + RW * j < BN) store_w4((stage * BN + wr + RW * j) * LDS4 + wc * (EW / 4), vw[j]);
  } else {
    const uint lk = t % BK, lr = t / BK;
    [[unroll]] for (uint j = 0; j < PER_X; ++j) sx[(stage * BM + lr + ROWS * j) * LDS4 + lk / 4][lk % 4] = float16_t(rx[j]);
    [[unroll]] for (uint j = 0; j < PER_W; ++j) sw[(stage * BN + lr + ROWS * j) * LDS4 + lk / 4][lk % 4] = float16_t(rw[j]);
  }
}

void main() {
  const uvec2 tile = gemm_tile_order(GROUP_M);
  tb = gl_WorkGroupID.z;
  tm0 = tile.x * BM;
  tn0 = tile.y * BN;
  const uint sg = gl_SubgroupID, lane = gl_SubgroupInvocationID;
  const uint sm = sg / SG_N, sn = sg % SG_N;

  coopmat<float, gl_ScopeSubgroup, FRAG_M, FRAG_N, gl_MatrixUseAccumulator> acc[FM * FN];
  [[unroll]] for (uint f = 0; f < FM * FN; ++f)
    acc[f] = coopmat<float, gl_ScopeSubgroup, FRAG_M, FRAG_N, gl_MatrixUseAccumulator>(0.0);

  const uint steps = (p.K + BK - 1) / BK;
  if (steps > 0) {
    load_step(0);
    store_step(0);
  }
  barrier();

  for (uint s = 0; s < steps; ++s) {
    const uint cur = s & 1u;
    const bool more = s + 1 < steps;
    if (more) load_step((s + 1) * BK);
    const uint xb = (cur * BM + sm * (FM * FRAG_M)) * LDS4, wb = (cur * BN + sn * (FN * FRAG_N)) * LDS4;
    [[unroll]] for (uint kk = 0; kk < BK; kk += FRAG_K) {
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_M, FRAG_K, gl_MatrixUseA> a[FM];
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_K, FRAG_N, gl_MatrixUseB> w[FN];
      [[unroll]] for (uint i = 0; i < FM; ++i)
        coopMatLoad(a[i], sx, xb + i * FRAG_M * LDS4 + kk / 4, LDS4, gl_CooperativeMatrixLayoutRowMajor);
      // B[k][n] = W[n][k]: W's rows in shared memory are B's columns.
      [[unroll]] for (uint j = 0; j < FN; ++j)
        coopMatLoad(w[j], sw, wb + j * FRAG_N * LDS4 + kk / 4, LDS4, gl_CooperativeMatrixLayoutColumnMajor);
      [[unroll]] for (uint i = 0; i < FM; ++i)
        [[unroll]] for (uint j = 0; j < FN; ++j)
          if (ABLATE != 2) acc[i * FN + j] = coopMatMulAdd(a[i], w[j], acc[i * FN + j]);
    }
    if (more) store_step(cur ^ 1u);
    barrier();
  }

  const uint st = sg * FRAG;
  [[unroll]] for (uint i = 0; i < FM; ++i)
    [[unroll]] for (uint j = 0; j < FN; ++j) {
#ifdef CONV_SHIFTED
      // Column-major: neighbouring lanes take neighbouring grid rows (pixels) of one output channel below, which are
      // neighbours in y's channel plane, so the stores are contiguous runs (row-major would scatter them over planes).
      coopMatStore(acc[i * FN + j], stage, st, FRAG_M, gl_CooperativeMatrixLayoutColumnMajor);
#else
      coopMatStore(acc[i * FN + j], stage, st, FRAG_N, gl_CooperativeMatrixLayoutRowMajor);
#endif
      subgroupMemoryBarrierShared();
      subgroupBarrier();
      const uint mb = tm0 + sm * (FM * FRAG_M) + i * FRAG_M, nb = tn0 + sn * (FN * FRAG_N) + j * FRAG_N;
#ifdef CONV_SHIFTED
      for (uint e = lane; e < FRAG; e += gl_SubgroupSize) {
        const uint m = mb + e % FRAG_M, n = nb + e / FRAG_M;
        if (m < p.M && n < p.N) store_conv_output(m, n, stage[st + e]);
      }
#else
      if (Y_F16) {
        for (uint e = 2u * lane; e < FRAG; e += 2u * gl_SubgroupSize) {
          const uint m = mb + e / FRAG_N, n = nb + e % FRAG_N;
          if (m < p.M && n < p.N) {
            const vec2 v = vec2(epilogue_value(tb, m, n, stage[st + e]), epilogue_value(tb, m, n + 1u, stage[st + e + 1u]));
            yh[(p.y_off + tb * p.y_bs + m * p.ldy + n) >> 1] = packHalf2x16(v);
          }
        }
      } else {
        for (uint e = lane; e < FRAG; e += gl_SubgroupSize) {
          const uint m = mb + e / FRAG_N, n = nb + e % FRAG_N;
          if (m < p.M && n < p.N) store_output(tb, m, n, stage[st + e]);
        }
      }
#endif
      subgroupMemoryBarrierShared();
      subgroupBarrier();  // every lane read the block before the next fragment overwrites it
    }
}
