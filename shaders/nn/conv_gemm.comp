#version 450
#extension GL_GOOGLE_include_directive : require
// Convolution as an implicit GEMM, with subgroup shuffles (see conv_gemm.glsl).
#include "conv_gemm.glsl"
