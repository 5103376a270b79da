#version 450
// Fixed-point path, pass 2b (devices without float atomics): like splat_forward_float, but each
// contribution is weighted relative to the strongest one of its pixel, exp(s_min − s) ≤ 1 with
// s = 50·ρ − log(w) (see splat_min_cost), and summed as unsigned integers scaled by 2^16:
// accum [F,H,W,4] = (Σw·(r+1)/2, Σw·(g+1)/2, Σw·(b+1)/2, Σw). Contributions below 2^-17 of the strongest
// one are dropped (they change the normalised colour by less than that); a pixel overflows only past
// 65536 full-strength contributions.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) readonly buffer FrameMax { uint framemax[]; };
layout(std430, binding = 2) readonly buffer Rgb { float rgb[]; };
layout(std430, binding = 3) readonly buffer Keys { uint keys[]; };
layout(std430, binding = 4) buffer Accum { uint accum[]; };
#include "splat_common.glsl"

const float SCALE = 65536.0;

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
  float rho = max_l > 0.0 ? log_depth(X2.z) / max_l : 0.0;
  const uint HW = p.H * p.W, j = y * p.W + x;
  vec3 c = vec3(rgb[(p.frame * 3u + 0u) * HW + j], rgb[(p.frame * 3u + 1u) * HW + j], rgb[(p.frame * 3u + 2u) * HW + j]);
  vec3 c01 = clamp((c + 1.0) * 0.5, 0.0, 1.0);
  for (int k = 0; k < 4; ++k) {
    int q = interior_index(corner[k]);
    if (q < 0 || !(w[k] > 0.0)) continue;
    float s = max(50.0 * rho - log(w[k]), 0.0);
    float s_min = uintBitsToFloat(0xFFFFFFFFu - keys[q]);
    float wk = min(exp(s_min - s), 1.0) * SCALE;
    if (wk < 0.5) continue;  // rounds to zero
    atomicAdd(accum[4 * q + 0], uint(wk * c01.r + 0.5));
    atomicAdd(accum[4 * q + 1], uint(wk * c01.g + 0.5));
    atomicAdd(accum[4 * q + 2], uint(wk * c01.b + 0.5));
    atomicAdd(accum[4 * q + 3], uint(wk + 0.5));
  }
}
