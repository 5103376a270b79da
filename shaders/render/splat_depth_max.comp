#version 450
// Pass 1 of the soft splat: per frame, max over all points of log(1 + clamp(z2, 0, 1000)) (z2 = target
// depth), stored as float bits (non-negative floats order like their bits). framemax must start at 0.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) readonly buffer Transforms { float T[]; };
layout(std430, binding = 2) buffer FrameMax { uint framemax[]; };
#include "splat_common.glsl"

shared float partial[256];

void main() {
  const uint f = gl_WorkGroupID.y;
  const uint HW = p.H * p.W;
  float m = 0.0;
  for (uint i = gl_GlobalInvocationID.x; i < HW; i += gl_NumWorkGroups.x * 256u) {
    vec3 X2 = transform_point(i % p.W, i / p.W, depth[f * HW + i], f * 16u);
    if (point_used(X2)) m = max(m, log_depth(X2.z));
  }
  partial[gl_LocalInvocationID.x] = m;
  barrier();
  for (uint s = 128u; s > 0u; s >>= 1) {
    if (gl_LocalInvocationID.x < s) partial[gl_LocalInvocationID.x] = max(partial[gl_LocalInvocationID.x], partial[gl_LocalInvocationID.x + s]);
    barrier();
  }
  if (gl_LocalInvocationID.x == 0u && partial[0] > 0.0) atomicMax(framemax[f], floatBitsToUint(partial[0]));
}
