#version 450
#extension GL_GOOGLE_include_directive : require
#define INVERSE 1
#define P2 1
#include "patchify.glsl"
