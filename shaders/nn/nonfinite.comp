#version 450
// NaN/Inf scan through a storage buffer (the body and its description: nonfinite.glsl). The view is rounded
// up to 16 bytes (views are at least 64-byte aligned, the padding lies inside the allocation).
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer X { uvec4 x[]; };
#define LOAD4(k) x[k]

#include "nonfinite.glsl"
