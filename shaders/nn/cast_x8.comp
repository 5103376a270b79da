#version 450
#extension GL_GOOGLE_include_directive : require
#define X8 1
#include "cast.glsl"
