#version 450
// Pass 3 of the soft splat: render = Σw·rgb / Σw clamped to [−1, 1] where weight landed, −1 in holes;
// mask = 1 where weight landed, else 0. FIXED_POINT selects how accum is read (see the forward passes); in
// the fixed-point path "weight landed" is read from keys (a point reached the pixel), so weights that
// round to zero still count, as Σw > 0 does in float.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint FIXED_POINT = 0;
layout(std430, binding = 0) readonly buffer Accum { uint accum[]; };
layout(std430, binding = 1) readonly buffer Keys { uint keys[]; };
layout(std430, binding = 2) writeonly buffer Render { float render[]; };
layout(std430, binding = 3) writeonly buffer Mask { float mask[]; };
layout(push_constant) uniform Push {
  uint H, W, frames;  // all frames of the chunk at once
} p;
#include "index.glsl"

void main() {
  const uint HW = p.H * p.W;
  const uint q = flat_index();
  if (q >= p.frames * HW) return;
  const uint f = q / HW, i = q % HW;
  vec3 c = vec3(-1.0);
  bool hit;
  if (FIXED_POINT == 0u) {
    float sw = uintBitsToFloat(accum[4 * q + 3]);
    hit = sw > 0.0;
    if (hit) c = vec3(uintBitsToFloat(accum[4 * q + 0]), uintBitsToFloat(accum[4 * q + 1]), uintBitsToFloat(accum[4 * q + 2])) / sw;
  } else {
    hit = keys[q] != 0u;
    float sw = float(accum[4 * q + 3]);
    if (hit && sw > 0.0) c = vec3(float(accum[4 * q + 0]), float(accum[4 * q + 1]), float(accum[4 * q + 2])) / sw * 2.0 - 1.0;
  }
  c = clamp(c, -1.0, 1.0);
  render[(f * 3u + 0u) * HW + i] = c.r;
  render[(f * 3u + 1u) * HW + i] = c.g;
  render[(f * 3u + 2u) * HW + i] = c.b;
  mask[q] = hit ? 1.0 : 0.0;
}
