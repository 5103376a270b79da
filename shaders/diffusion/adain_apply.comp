#version 450
#extension GL_GOOGLE_include_directive : require
// Per-channel AdaIN on a latent viewed as [outer, C, inner]:
// y = (x − μx[c]) / √(σ²x[c] + eps) · √(σ²s[c] + eps) + μs[c].
layout(local_size_x = 64) in;
#include "index.glsl"

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) readonly buffer MeanX { float mean_x[]; };
layout(std430, binding = 2) readonly buffer VarX { float var_x[]; };
layout(std430, binding = 3) readonly buffer MeanS { float mean_s[]; };
layout(std430, binding = 4) readonly buffer VarS { float var_s[]; };
layout(std430, binding = 5) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint n, channels, inner;
  float eps;
  uint plane0;  // the plane (of `inner` elements) where element 0 lies: split calls bind plane ranges
} p;

void main() {
  uint i = flat_index();
  if (i >= p.n) return;
  uint c = (p.plane0 + i / p.inner) % p.channels;
  float scale = sqrt(var_s[c] + p.eps) / sqrt(var_x[c] + p.eps);
  y[i] = (x[i] - mean_x[c]) * scale + mean_s[c];
}
