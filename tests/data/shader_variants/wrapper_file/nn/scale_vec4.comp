#version 450
#extension GL_GOOGLE_include_directive : require
// The vec4 variant.
#define VEC4 1
#include "scale.glsl"
