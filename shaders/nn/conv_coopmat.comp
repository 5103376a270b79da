#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_shader_subgroup_basic : require
// Convolution on tensor cores (see conv_coopmat.glsl; its fp32 twin is conv_coopmat_twin.comp).
#define CONV_COOPMAT 1
#include "conv_coopmat.glsl"
