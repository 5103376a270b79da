#version 450
#extension GL_GOOGLE_include_directive : require
// Convolution as an implicit GEMM for devices without subgroup shuffles: every lane fetches every pixel.
#define CONV_NO_SUBGROUPS
#include "conv_gemm.glsl"
