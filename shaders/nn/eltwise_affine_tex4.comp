#version 450
#extension GL_GOOGLE_include_directive : require
#define TEXEL 1
#include "eltwise_affine.glsl"
