#version 450
#extension GL_GOOGLE_include_directive : require
// The tensor-core convolution's fp32 twin (see conv_coopmat.glsl): same tiles, loads, fp16 rounding and
// epilogue, the product by FMA; what the tests run on devices without cooperative matrices.
#include "conv_coopmat.glsl"
