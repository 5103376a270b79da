#version 450
// NaN/Inf scan reading the range through a uniform texel buffer (RGBA32UI), ~3x cheaper per load than a
// storage buffer on CPU drivers (docs/design.md §8). The body and its description: nonfinite.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_samplerless_texture_functions : require

layout(local_size_x = 64) in;

layout(binding = 0) uniform utextureBuffer xt;
#define LOAD4(k) texelFetch(xt, int(k))

#include "nonfinite.glsl"
