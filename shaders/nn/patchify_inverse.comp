#version 450
#extension GL_GOOGLE_include_directive : require
#define INVERSE 1
#include "patchify.glsl"
