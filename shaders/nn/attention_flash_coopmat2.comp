#version 450
#extension GL_KHR_cooperative_matrix : require
#extension GL_NV_cooperative_matrix2 : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int32 : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_GOOGLE_include_directive : require
// Flash attention on tensor cores with the softmax in the matrices' registers (VK_NV_cooperative_matrix2's
// reductions, per-element operations and accumulator-to-operand conversions, at subgroup scope): the variant of
// attention_flash_coopmat.comp that ops_attention_flash.cpp runs where the device has those three features
// (DeviceTuning::attention_coopmat2). Same layout, bindings, push constants, K/V staging, fp16 operands, exp2
// domain and fp32 accumulation; what differs is that S, P and O never leave the cooperative matrices:
//   S_j = Q·K_jᵀ (ROWS x FRAG_N accumulators, one per FRAG_N keys of the tile), keys past the end set to -FLT_MAX;
//   the row max over the tile by coopMatReduceNV, the running max m and sum l kept as accumulators whose rows
//   hold each row's value in every column; P_j = exp2(S_j - m) rounded to fp16 in place (so the row sum adds the
//   P that P·V reads), converted to A operands; O_d = O_d·exp2(m_old - m) + Σ_j P_j·V_jd.
// Q is rounded as given and the fp32 scores scaled by scale·log2(e), as in the KHR kernel.
// No shared memory for scores or P (the KHR kernel's sS/sP and its lanes' copies of O, the bank-conflict and
// shared-traffic cost of that kernel); shared memory holds K and V and one ROWS x FRAG_N fp32 block per subgroup
// that stages Q on the way in and O on the way out, one fragment column at a time (rows past the end are neither
// read nor written). So 8 subgroups (128 query rows at 16x16x16, one K/V tile per 128 rows) take 28 KiB at
// head_dim 64 (tensor/coopmat_layout.cpp: attention_coopmat2_shared_bytes).
// Needs the fragment's N equal to its K (the scores' accumulators become P's A operands, Q's become A).
// Its twin on devices without these features is attention_flash_coopmat.comp, which the tests compare it with.
#include "../common/attention_flash_coopmat_decl.glsl"
#include "../common/f16.glsl"

const int OP = FRAG_N + 4;  // sO row pitch (floats): 16-byte aligned, off the 128-byte bank period
const int F4 = FRAG_N / 4;  // vec4 per row of a fragment column (FRAG_K = FRAG_N)
shared float sO[SUBGROUPS * ROWS * OP];  // per subgroup: a fragment column of Q (fp32) in, of O out

#define ACC coopmat<float, gl_ScopeSubgroup, ROWS, FRAG_N, gl_MatrixUseAccumulator>
#define OPA coopmat<float16_t, gl_ScopeSubgroup, ROWS, FRAG_K, gl_MatrixUseA>
#define OPB coopmat<float16_t, gl_ScopeSubgroup, FRAG_K, FRAG_N, gl_MatrixUseB>

float op_max(const in float a, const in float b) { return max(a, b); }
float op_add(const in float a, const in float b) { return a + b; }
float elem_max(const in uint32_t r, const in uint32_t c, const in float a, const in float b) { return max(a, b); }
float elem_add(const in uint32_t r, const in uint32_t c, const in float a, const in float b) { return a + b; }
float elem_mul(const in uint32_t r, const in uint32_t c, const in float a, const in float b) { return a * b; }
float elem_div(const in uint32_t r, const in uint32_t c, const in float a, const in float b) { return a / b; }
// Keys at or past kv_len (column c of the block that starts at key `first`) take no part.
float elem_mask(const in uint32_t r, const in uint32_t c, const in float s, const in uint32_t first, const in uint32_t kv_len) {
  return first + c < kv_len ? s : MASKED;
}
// exp2(m_old - m_new): the factor that moves the row's sum and O to the new max (0 before the first key).
float elem_rescale(const in uint32_t r, const in uint32_t c, const in float m_old, const in float m_new) {
  return exp2(m_old - m_new);
}
// P = exp2(S - m), rounded to fp16 here so that the row sum adds exactly the P that P·V multiplies.
float elem_exp(const in uint32_t r, const in uint32_t c, const in float s, const in float m) {
  return float(float16_t(exp2(s - m)));
}
float elem_fma(const in uint32_t r, const in uint32_t c, const in float l, const in float alpha, const in float sum) {
  return l * alpha + sum;
}

void main() {
  const uint h = gl_WorkGroupID.y, b = gl_WorkGroupID.z;
  const uint sg = gl_SubgroupID, lane = gl_SubgroupInvocationID;
  const uint sgO = sg * ROWS * OP;
  const uint row_base = gl_WorkGroupID.x * (SUBGROUPS * ROWS) + sg * ROWS;
  const uint kbase = b * p.k_bstride + h * p.k_hstride + p.k_off;
  const uint vbase = b * p.v_bstride + h * p.v_hstride + p.v_off;

  // ---- Q (this subgroup's ROWS rows), via sO, to fp16 A operands as given (the scores are scaled below) ----
  // Each value is rounded to fp16 here (nearest even, on the bits: f16.glsl), so the matrix conversion to the A operand
  // is exact: lavapipe's rounds otherwise, and an f32 q then gave other bits than the same q rounded to fp16.
  const float qscale = p.scale * LOG2E;  // into the exp2 domain, in fp32
  OPA qf[D / FRAG_K];
  [[unroll]] for (int d = 0; d < D / FRAG_K; ++d) {
    for (uint i = lane; i < ROWS * F4; i += LANES) {
      const uint rr = i / F4, c = i % F4;
      const uint row = min(row_base + rr, p.q_len - 1);  // rows past the end: a copy of the last, never stored
      const vec4 x = load_q(b, h, row, d * F4 + c);
      const uint at = sgO + rr * OP + c * 4;
      sO[at] = f16_value(x.x);
      sO[at + 1] = f16_value(x.y);
      sO[at + 2] = f16_value(x.z);
      sO[at + 3] = f16_value(x.w);
    }
    subgroupMemoryBarrierShared();
    subgroupBarrier();
    ACC q32;
    coopMatLoad(q32, sO, sgO, OP, gl_CooperativeMatrixLayoutRowMajor);
    qf[d] = OPA(q32);
    subgroupMemoryBarrierShared();
    subgroupBarrier();  // every lane has its part of the fragment before the next column overwrites the block
  }

  ACC o[D / FRAG_N];
  [[unroll]] for (int d = 0; d < D / FRAG_N; ++d) o[d] = ACC(0.0);
  ACC m = ACC(MASKED), l = ACC(0.0);

  load_kv(0, kbase, vbase);
  for (uint tile0 = 0; tile0 < p.kv_len; tile0 += BK) {
    barrier();  // every subgroup is done with the previous tile
    store_kv();
    barrier();
    if (tile0 + BK < p.kv_len) load_kv(tile0 + BK, kbase, vbase);  // in flight during this tile's math

    // ---- S_j = Q·K_jᵀ; the last tile's keys past the end masked ----
    ACC s[BK / FRAG_N];
    [[unroll]] for (int j = 0; j < BK / FRAG_N; ++j) {
      s[j] = ACC(0.0);
      [[unroll]] for (int d = 0; d < D / FRAG_K; ++d) {
        OPB kf;  // Kᵀ as B is K [key][dim] read column-major
        coopMatLoad(kf, sK, j * FRAG_N * KP + d * FRAG_K, KP, gl_CooperativeMatrixLayoutColumnMajor);
        s[j] = coopMatMulAdd(qf[d], kf, s[j]);
      }
      s[j] = s[j] * qscale;
    }
    if (tile0 + BK > p.kv_len)
      [[unroll]] for (int j = 0; j < BK / FRAG_N; ++j)
        coopMatPerElementNV(s[j], s[j], elem_mask, uint32_t(tile0 + j * FRAG_N), uint32_t(p.kv_len));

    // ---- online softmax: new row max, rescale factor, P (fp16-exact), row sums ----
    ACC t = s[0];
    [[unroll]] for (int j = 1; j < BK / FRAG_N; ++j) coopMatPerElementNV(t, t, elem_max, s[j]);
    ACC tile_max;
    coopMatReduceNV(tile_max, t, gl_CooperativeMatrixReduceRowNV, op_max);
    ACC m_new, alpha;
    coopMatPerElementNV(m_new, m, elem_max, tile_max);
    coopMatPerElementNV(alpha, m, elem_rescale, m_new);
    m = m_new;
    ACC sum = ACC(0.0);
    [[unroll]] for (int j = 0; j < BK / FRAG_N; ++j) {
      coopMatPerElementNV(s[j], s[j], elem_exp, m);
      coopMatPerElementNV(sum, sum, elem_add, s[j]);
    }
    ACC row_sum;
    coopMatReduceNV(row_sum, sum, gl_CooperativeMatrixReduceRowNV, op_add);
    coopMatPerElementNV(l, l, elem_fma, alpha, row_sum);

    // ---- O = O·alpha + P·V ----
    [[unroll]] for (int d = 0; d < D / FRAG_N; ++d) coopMatPerElementNV(o[d], o[d], elem_mul, alpha);
    [[unroll]] for (int j = 0; j < BK / FRAG_K; ++j) {
      const OPA pf = OPA(s[j]);
      [[unroll]] for (int d = 0; d < D / FRAG_N; ++d) {
        OPB vf;
        coopMatLoad(vf, sV, j * FRAG_K * KP + d * FRAG_N, KP, gl_CooperativeMatrixLayoutRowMajor);
        o[d] = coopMatMulAdd(pf, vf, o[d]);
      }
    }
  }

  // ---- O / l through sO to the rows that exist, one fragment column at a time ----
  [[unroll]] for (int d = 0; d < D / FRAG_N; ++d) {
    coopMatPerElementNV(o[d], o[d], elem_div, l);
    coopMatStore(o[d], sO, sgO, OP, gl_CooperativeMatrixLayoutRowMajor);
    subgroupMemoryBarrierShared();
    subgroupBarrier();
    for (uint i = lane; i < ROWS * F4; i += LANES) {
      const uint rr = i / F4, c = i % F4, row = row_base + rr;
      if (row < p.q_len) {
        const uint at = sgO + rr * OP + c * 4;
        store_o((b * p.q_len + row) * p.o_stride + p.o_off + h * D4 + d * F4 + c,
                vec4(sO[at], sO[at + 1], sO[at + 2], sO[at + 3]));
      }
    }
    subgroupMemoryBarrierShared();
    subgroupBarrier();  // every lane wrote its rows before the next column overwrites the block
  }
}
