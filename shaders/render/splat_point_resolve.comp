#version 450
// Hard z-buffer point mode, resolve: the colour of the winning point (see splat_point), −1 and mask 0 where
// no point landed.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Rgb { float rgb[]; };
layout(std430, binding = 1) readonly buffer IdKey { uint idkey[]; };
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
  uint key = idkey[q];
  vec3 c = vec3(-1.0);
  if (key != 0u) {
    uint src = 0xFFFFFFFFu - key;
    c = clamp(vec3(rgb[(f * 3u + 0u) * HW + src], rgb[(f * 3u + 1u) * HW + src], rgb[(f * 3u + 2u) * HW + src]), -1.0, 1.0);
  }
  render[(f * 3u + 0u) * HW + i] = c.r;
  render[(f * 3u + 1u) * HW + i] = c.g;
  render[(f * 3u + 2u) * HW + i] = c.b;
  mask[q] = key != 0u ? 1.0 : 0.0;
}
