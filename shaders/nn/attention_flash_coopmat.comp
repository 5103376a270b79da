#version 450
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_EXT_control_flow_attributes : require
// Flash attention on tensor cores (DeviceTuning::attention = coopmat): out = softmax(q·kᵀ·scale)·v per
// (batch, head). S = Q·Kᵀ and O_tile = P·V are 16x16x16 cooperative-matrix products with fp16 operands and
// fp32 accumulators; the online softmax (running max, sum, rescaling of O) is fp32 in the exp2 domain.
//
// Work split: 128 invocations = 4 subgroups of 32 lanes (kernel_tuning.cpp picks this family only where
// subgroups have 32 lanes); a workgroup takes 64 query rows of one (batch, head), each subgroup 16 of them.
// Per tile of BK keys: the workgroup stages K and V (fp16) in shared memory; each subgroup computes its
// 16 x BK scores into its shared slice (fp32); its lanes (2 per row, BK/2 columns each) take the row's
// max and sum (the pair combined by a shuffle), write P (fp16) and rescale their share of O; P·V goes to
// the same fp32 slice, and each lane adds its 16 x D/2 share into O, which it keeps in registers (the
// fragment layout of a cooperative matrix is opaque, so per-row rescaling happens outside it).
//
// fp16 operands: Q is pre-multiplied by scale·log2(e) before rounding; |q·scale·log2 e|, |k| or |v| over
// 65504 becomes inf (activations of the supported models are far below that). P is in [0, 1]; the row sum
// adds the same fp16-rounded P that P·V uses, so the weights stay normalised.
//
// Limits (ops_attention_flash.cpp checks them): head_dim D a multiple of 16 and at most BK (the O tile
// reuses the scores' slice); shared memory 2·BK·D·2 + 64·BK·4 + 64·BK·2 bytes (40 KiB at D = BK = 64).
// No bias, key mask or split-key state: such calls run on attention.comp. Not double-buffered.
#extension GL_GOOGLE_include_directive : require
#include "attention_flash_coopmat_decl.glsl"

#define SG_ID gl_SubgroupID
#define SG_LANE gl_SubgroupInvocationID
#define SG_BARRIER()            \
  subgroupMemoryBarrierShared(); \
  subgroupBarrier()
#define PAIR_XOR(x) subgroupShuffleXor(x, 1)
// Q as D/16 A fragments, kept for the whole key loop.
#define LOAD_Q()                                                          \
  coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseA> qf[D16];   \
  [[unroll]] for (int d = 0; d < D16; ++d)                                \
    coopMatLoad(qf[d], sP, sgP + d * 16, D, gl_CooperativeMatrixLayoutRowMajor)
// Kᵀ as B is K [key][dim] read column-major.
#define SCORES()                                                                                \
  [[unroll]] for (int j = 0; j < BK16; ++j) {                                                   \
    coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator> s =                      \
        coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator>(0.0);                 \
    [[unroll]] for (int d = 0; d < D16; ++d) {                                                  \
      coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseB> kf;                           \
      coopMatLoad(kf, sK, j * 16 * D + d * 16, D, gl_CooperativeMatrixLayoutColumnMajor);       \
      s = coopMatMulAdd(qf[d], kf, s);                                                          \
    }                                                                                           \
    coopMatStore(s, sS, sgS + j * 16, BK, gl_CooperativeMatrixLayoutRowMajor);                 \
  }
#define PV()                                                                                    \
  coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseA> pf[BK16];                         \
  [[unroll]] for (int j = 0; j < BK16; ++j)                                                     \
    coopMatLoad(pf[j], sP, sgP + j * 16, BK, gl_CooperativeMatrixLayoutRowMajor);               \
  [[unroll]] for (int d = 0; d < D16; ++d) {                                                    \
    coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator> ot =                     \
        coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator>(0.0);                 \
    [[unroll]] for (int j = 0; j < BK16; ++j) {                                                 \
      coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseB> vf;                           \
      coopMatLoad(vf, sV, j * 16 * D + d * 16, D, gl_CooperativeMatrixLayoutRowMajor);          \
      ot = coopMatMulAdd(pf[j], vf, ot);                                                        \
    }                                                                                           \
    coopMatStore(ot, sS, sgS + d * 16, D, gl_CooperativeMatrixLayoutRowMajor);                 \
  }

#include "attention_flash_coopmat_main.glsl"
