#version 450
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_GOOGLE_include_directive : require
// The fp32 twin of attention_flash_coopmat.comp, for CPU drivers without cooperative matrices (lavapipe):
// the same staging, fp16 rounding, softmax, O accumulation and epilogue (one main(), shared through
// attention_flash_coopmat_main.glsl), with the two products done by plain fp32 FMA on the same fp16
// operands and the 4 x 32-lane "subgroups" emulated by the workgroup (workgroup barriers, a shared-memory
// pair exchange). Only the cooperative-matrix calls themselves stay untested on lavapipe. Tests only
// (DeviceTuning::attention_coopmat_twin): Q lives in its own shared copy, which lavapipe's 32 KiB holds at
// small D and BK (e.g. D = 32, BK = 32).
#include "attention_flash_coopmat_decl.glsl"

shared float16_t sQ[SUBGROUPS * ROWS * D];
shared float xch[SUBGROUPS * 32];

#define SG_ID (gl_LocalInvocationID.x / 32)
#define SG_LANE (gl_LocalInvocationID.x % 32)
// barrier() alone: glslang gives it workgroup-memory semantics (memoryBarrierShared() would use Device scope).
#define SG_BARRIER() barrier()
float pair_xor(float x) {
  xch[gl_LocalInvocationID.x] = x;
  barrier();
  const float y = xch[gl_LocalInvocationID.x ^ 1];
  barrier();
  return y;
}
#define PAIR_XOR(x) pair_xor(x)
#define LOAD_Q() \
  for (uint i = lane; i < ROWS * D; i += 32) sQ[sg * ROWS * D + i] = sP[sgP + i]
#define SCORES()                                                               \
  for (uint e = lane; e < ROWS * BK; e += 32) {                                \
    const uint i = e / BK, n = e % BK;                                         \
    float acc = 0;                                                             \
    for (int k = 0; k < D; ++k)                                                \
      acc = fma(float(sQ[sg * ROWS * D + i * D + k]), float(sK[n * D + k]), acc); \
    sS[sgS + i * BK + n] = acc;                                                \
  }
#define PV()                                                                   \
  for (uint e = lane; e < ROWS * D; e += 32) {                                 \
    const uint i = e / D, n = e % D;                                           \
    float acc = 0;                                                             \
    for (int k = 0; k < BK; ++k) acc = fma(float(sP[sgP + i * BK + k]), float(sV[k * D + n]), acc); \
    sS[sgS + i * D + n] = acc;                                                 \
  }

#include "attention_flash_coopmat_main.glsl"
