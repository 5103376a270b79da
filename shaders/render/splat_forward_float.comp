#version 450
// Pass 2 of the soft splat, float-atomics path (VK_EXT_shader_atomic_float): every point adds w·rgb and w
// to its four footprint pixels, w = bilinear weight / exp(50 · ρ) (official §3.5). accum [F,H,W,4] = (Σw·r,
// Σw·g, Σw·b, Σw) starts at 0.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) readonly buffer Transforms { float T[]; };
layout(std430, binding = 2) readonly buffer FrameMax { uint framemax[]; };
layout(std430, binding = 3) readonly buffer Rgb { float rgb[]; };
layout(std430, binding = 4) buffer Accum { float accum[]; };
#include "splat_common.glsl"

void main() {
  const uint f = gl_WorkGroupID.y;
  const uint HW = p.H * p.W;
  const float max_l = uintBitsToFloat(framemax[f]);
  for (uint i = gl_GlobalInvocationID.x; i < HW; i += gl_NumWorkGroups.x * 64u) {
    vec3 X2 = transform_point(i % p.W, i / p.W, depth[f * HW + i], f * 16u);
    if (!point_used(X2)) continue;
    ivec2 corner[4];
    float w[4];
    if (!footprint(project_point(X2), corner, w)) continue;
    float dw = max_l > 0.0 ? exp(log_depth(X2.z) / max_l * 50.0) : 1.0;
    vec3 c = vec3(rgb[(f * 3u + 0u) * HW + i], rgb[(f * 3u + 1u) * HW + i], rgb[(f * 3u + 2u) * HW + i]);
    for (int k = 0; k < 4; ++k) {
      int q = interior_index(f, corner[k]);
      if (q < 0) continue;
      float wk = w[k] / dw;
      atomicAdd(accum[4 * q + 0], wk * c.r);
      atomicAdd(accum[4 * q + 1], wk * c.g);
      atomicAdd(accum[4 * q + 2], wk * c.b);
      atomicAdd(accum[4 * q + 3], wk);
    }
  }
}
