#version 450
// Pass 2 of the soft splat, float-atomics path (VK_EXT_shader_atomic_float): every point adds w·rgb and w
// to its four footprint pixels, w = bilinear weight / exp(50 · ρ) (official §3.5). accum [F,H,W,4] = (Σw·r,
// Σw·g, Σw·b, Σw) starts at 0.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) readonly buffer FrameMax { uint framemax[]; };
layout(std430, binding = 2) readonly buffer Rgb { float rgb[]; };
layout(std430, binding = 3) buffer Accum { float accum[]; };
#include "splat_common.glsl"

void main() {
  uint x, y, i;
  if (!source_pixel(x, y, i)) return;
  const MovedPoint m = move_point(x, y, depth[i]);
  const vec3 X2 = m.X2;
  if (!point_used(X2)) return;
  ivec2 corner[4];
  float w[4];
  if (!footprint(project_point(x, y, m), corner, w)) return;
  const float max_l = uintBitsToFloat(framemax[p.frame]);
  float dw = max_l > 0.0 ? exp(log_depth(X2.z) / max_l * 50.0) : 1.0;
  const uint HW = p.H * p.W, j = y * p.W + x;
  vec3 c = vec3(rgb[(p.frame * 3u + 0u) * HW + j], rgb[(p.frame * 3u + 1u) * HW + j], rgb[(p.frame * 3u + 2u) * HW + j]);
  for (int k = 0; k < 4; ++k) {
    int q = interior_index(corner[k]);
    if (q < 0) continue;
    float wk = w[k] / dw;
    atomicAdd(accum[4 * q + 0], wk * c.r);
    atomicAdd(accum[4 * q + 1], wk * c.g);
    atomicAdd(accum[4 * q + 2], wk * c.b);
    atomicAdd(accum[4 * q + 3], wk);
  }
}
