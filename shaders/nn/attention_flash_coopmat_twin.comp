#version 450
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_GOOGLE_include_directive : require
// The fp32 twin of attention_flash_coopmat.comp, for CPU drivers without cooperative matrices (lavapipe):
// the same staging, fp16 rounding, softmax, O accumulation and epilogue (one main(), shared through
// attention_flash_coopmat_main.glsl), with the two products done by plain fp32 FMA on the same fp16
// operands and the SUBGROUPS x LANES "subgroups" emulated by the workgroup (workgroup barriers, a
// shared-memory lane exchange). Only the cooperative-matrix calls themselves stay untested on lavapipe. Tests only
// (DeviceTuning::attention_coopmat_twin): Q lives in its own shared copy, which lavapipe's 32 KiB holds at
// small D and BK (e.g. D = 32, BK = 32).
#include "attention_flash_coopmat_decl.glsl"

shared float16_t sQ[SUBGROUPS * ROWS * D];
shared float xch[SUBGROUPS * LANES];

#define SG_ID (gl_LocalInvocationID.x / LANES)
#define SG_LANE (gl_LocalInvocationID.x % LANES)
// barrier() alone: glslang gives it workgroup-memory semantics (memoryBarrierShared() would use Device scope).
#define SG_BARRIER() barrier()
float lane_xor(float x, int mask) {
  xch[gl_LocalInvocationID.x] = x;
  barrier();
  const float y = xch[gl_LocalInvocationID.x ^ uint(mask)];
  barrier();
  return y;
}
#define LANE_XOR(x, mask) lane_xor(x, mask)
#define LOAD_Q() \
  for (uint i = lane; i < ROWS * D; i += LANES) sQ[sg * ROWS * D + i] = sP[sgP + (i / D) * PP + i % D]
#define SCORES()                                                               \
  for (uint e = lane; e < ROWS * BK; e += LANES) {                             \
    const uint i = e / BK, n = e % BK;                                         \
    float acc = 0;                                                             \
    for (int k = 0; k < D; ++k)                                                \
      acc = fma(float(sQ[sg * ROWS * D + i * D + k]), float(sK[n * KP + k]), acc); \
    sS[sgS + i * SP + n] = acc * qscale;                                       \
  }
#define PV()                                                                   \
  for (uint e = lane; e < ROWS * D; e += LANES) {                              \
    const uint i = e / D, n = e % D;                                           \
    float acc = 0;                                                             \
    for (int k = 0; k < BK; ++k) acc = fma(float(sP[sgP + i * PP + k]), float(sV[k * KP + n]), acc); \
    sS[sgS + i * SP + n] = acc;                                                \
  }

#include "attention_flash_coopmat_main.glsl"
