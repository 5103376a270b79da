#version 450
#extension GL_GOOGLE_include_directive : require
#define VEC4 1
#define TEXEL 1
#include "permute.glsl"
