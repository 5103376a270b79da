#version 450
#extension GL_GOOGLE_include_directive : require
#define P2 1
#include "patchify.glsl"
