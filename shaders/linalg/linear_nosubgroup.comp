#version 450
#extension GL_GOOGLE_include_directive : require
// Linear layer Y = epilogue(X·Wᵀ) for devices without subgroup shuffles: every lane fetches its rows itself.
// The kernel and its documentation: linear_kernel.glsl.
#define LINEAR_NO_SUBGROUPS 1
#include "linear_kernel.glsl"
