#version 450
// Fixed-point path, pass 2a: per pixel, the strongest contribution that reaches it, as the smallest cost
// s = 50·ρ − log(w) (the float path's weight is w·exp(−50ρ) = exp(−s)), stored as key = 0xFFFFFFFF −
// floatBits(s) with atomicMax (s ≥ 0, so float bits order like values; key 0 = nothing landed, the buffer
// starts zeroed). Pass 2b weighs every contribution relative to this strongest one, exp(s_min − s) ≤ 1, so
// the fixed-point sums stay inside 32 bits and never vanish where a point landed; the common factor
// cancels in the normalisation.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) readonly buffer FrameMax { uint framemax[]; };
layout(std430, binding = 2) buffer Keys { uint keys[]; };
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
  float rho = max_l > 0.0 ? log_depth(X2.z) / max_l : 0.0;
  for (int k = 0; k < 4; ++k) {
    int q = interior_index(corner[k]);
    if (q < 0 || !(w[k] > 0.0)) continue;
    float s = max(50.0 * rho - log(w[k]), 0.0);
    atomicMax(keys[q], 0xFFFFFFFFu - floatBitsToUint(s));
  }
}
