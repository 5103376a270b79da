#version 450
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_EXT_control_flow_attributes : require
// Flash attention on tensor cores (DeviceTuning::attention = coopmat): out = softmax(q·kᵀ·scale)·v per
// (batch, head). S = Q·Kᵀ and O_tile = P·V are cooperative-matrix products with fp16 operands and fp32
// accumulators; the online softmax (running max, sum, rescaling of O) is fp32 in the exp2 domain.
//
// Work split (the layout from the tuning table, attention_flash_coopmat_decl.glsl): SUBGROUPS subgroups of
// LANES lanes; a workgroup takes SUBGROUPS x ROWS query rows of one (batch, head), each subgroup ROWS of them
// (the fragment's M). The H200: 4 subgroups of 32 lanes at 16x16x16 (64 rows); lavapipe: 4 of 8 lanes at
// 8x8x8 (32 rows). Per tile of BK keys: the workgroup stages K and V (fp16) in shared memory; each subgroup
// computes its ROWS x BK scores into its shared slice (fp32); its lanes (LPR per row, or RPL rows per lane)
// take each row's max and sum (a row's lanes combined by shuffles), write P (fp16) and rescale their share
// of O; P·V goes to the same fp32 slice, and each lane adds its share into O, which it keeps in registers
// (the fragment layout of a cooperative matrix is opaque, so per-row rescaling happens outside it).
//
// fp16 operands: Q, K and V are rounded once (here from f32, or given fp16: the same values then, so the same bits),
// and the fp32 scores are scaled by scale·log2(e) (as SDPA scales its fp32 scores); |q|, |k| or |v| over 65504
// becomes inf (activations of the supported models are far below that). P is in [0, 1]; the row sum adds the same
// fp16-rounded P that P·V uses, so the weights stay normalised.
//
// Limits (tensor/coopmat_layout.cpp checks them): head_dim D a multiple of the fragment's N and K and at most
// BK (the O tile reuses the scores' slice); shared memory 2·BK·(D + 8)·2 + SUBGROUPS·ROWS·((BK + 4)·4 + (BK + 8)·2)
// bytes, rows padded against bank conflicts (44 KiB on the H200 at D = BK = 64). No bias, key mask or split-key
// state: such calls run on attention.comp. K and V are prefetched: the next tile is read into registers during this
// tile's math (attention_flash_coopmat_decl.glsl: load_kv, store_kv).
#extension GL_GOOGLE_include_directive : require
#include "attention_flash_coopmat_decl.glsl"

#define SG_ID gl_SubgroupID
#define SG_LANE gl_SubgroupInvocationID
#define SG_BARRIER()            \
  subgroupMemoryBarrierShared(); \
  subgroupBarrier()
#define LANE_XOR(x, mask) subgroupShuffleXor(x, mask)
// Q as D/FRAG_K A fragments, kept for the whole key loop.
#define LOAD_Q()                                                                 \
  coopmat<float16_t, gl_ScopeSubgroup, ROWS, FRAG_K, gl_MatrixUseA> qf[D / FRAG_K]; \
  [[unroll]] for (int d = 0; d < D / FRAG_K; ++d)                               \
    coopMatLoad(qf[d], sP, sgP + d * FRAG_K, PP, gl_CooperativeMatrixLayoutRowMajor)
// Kᵀ as B is K [key][dim] read column-major.
#define SCORES()                                                                                \
  [[unroll]] for (int j = 0; j < BK / FRAG_N; ++j) {                                            \
    coopmat<float, gl_ScopeSubgroup, ROWS, FRAG_N, gl_MatrixUseAccumulator> s =                 \
        coopmat<float, gl_ScopeSubgroup, ROWS, FRAG_N, gl_MatrixUseAccumulator>(0.0);           \
    [[unroll]] for (int d = 0; d < D / FRAG_K; ++d) {                                           \
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_K, FRAG_N, gl_MatrixUseB> kf;                   \
      coopMatLoad(kf, sK, j * FRAG_N * KP + d * FRAG_K, KP, gl_CooperativeMatrixLayoutColumnMajor); \
      s = coopMatMulAdd(qf[d], kf, s);                                                          \
    }                                                                                           \
    s = s * qscale;                                                                             \
    coopMatStore(s, sS, sgS + j * FRAG_N, SP, gl_CooperativeMatrixLayoutRowMajor);              \
  }
#define PV()                                                                                    \
  coopmat<float16_t, gl_ScopeSubgroup, ROWS, FRAG_K, gl_MatrixUseA> pf[BK / FRAG_K];            \
  [[unroll]] for (int j = 0; j < BK / FRAG_K; ++j)                                              \
    coopMatLoad(pf[j], sP, sgP + j * FRAG_K, PP, gl_CooperativeMatrixLayoutRowMajor);           \
  [[unroll]] for (int d = 0; d < D / FRAG_N; ++d) {                                             \
    coopmat<float, gl_ScopeSubgroup, ROWS, FRAG_N, gl_MatrixUseAccumulator> ot =                \
        coopmat<float, gl_ScopeSubgroup, ROWS, FRAG_N, gl_MatrixUseAccumulator>(0.0);           \
    [[unroll]] for (int j = 0; j < BK / FRAG_K; ++j) {                                          \
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_K, FRAG_N, gl_MatrixUseB> vf;                   \
      coopMatLoad(vf, sV, j * FRAG_K * KP + d * FRAG_N, KP, gl_CooperativeMatrixLayoutRowMajor); \
      ot = coopMatMulAdd(pf[j], vf, ot);                                                        \
    }                                                                                           \
    coopMatStore(ot, sS, sgS + d * FRAG_N, SP, gl_CooperativeMatrixLayoutRowMajor);              \
  }

#include "attention_flash_coopmat_main.glsl"
