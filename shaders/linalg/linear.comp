#version 450
#extension GL_GOOGLE_include_directive : require
// Linear layer Y = epilogue(X·Wᵀ), the variant with subgroup shuffles (every Vulkan 1.1+ GPU and lavapipe).
// The kernel and its documentation: linear_kernel.glsl.
#include "linear_kernel.glsl"
