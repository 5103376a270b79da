#version 450
#extension GL_GOOGLE_include_directive : require
// Classifier-free guidance on a batch-2 model output v = [uncond; cond] (n elements each):
// guided = uncond + g·(cond − uncond). One binding for v, so no view starts at an unaligned offset.
layout(local_size_x = 64) in;
#include "index.glsl"

layout(std430, binding = 0) readonly buffer V { float v[]; };
layout(std430, binding = 1) writeonly buffer G { float guided[]; };
layout(push_constant) uniform Push { uint n; float scale; } p;

void main() {
  uint i = flat_index();
  if (i >= p.n) return;
  float u = v[i];
  guided[i] = u + p.scale * (v[p.n + i] - u);
}
