#version 450
#extension GL_GOOGLE_include_directive : require
// DiagonalGaussianDistribution of the CogVideoX VAE: moments [B, 2*Cl, S] (S = F*H*W) is chunked on channels
// into mean and logvar; std = exp(0.5 * clamp(logvar, -30, 20)). One invocation per output element.
layout(local_size_x = 64) in;
#include "index.glsl"  // after local_size: flat_index() reads gl_WorkGroupSize
layout(std430, binding = 0) readonly buffer Moments { float moments[]; };
layout(std430, binding = 1) writeonly buffer Mean { float mean_out[]; };
layout(std430, binding = 2) writeonly buffer Std { float std_out[]; };
layout(push_constant) uniform Push {
  uint n;      // B * Cl * S
  uint half_;  // Cl * S: elements of one chunk per batch item
} pc;

void main() {
  const uint i = flat_index();
  if (i >= pc.n) return;
  const uint b = i / pc.half_, r = i - b * pc.half_;
  const uint base = b * 2u * pc.half_ + r;
  mean_out[i] = moments[base];
  const float logvar = clamp(moments[base + pc.half_], -30.0, 20.0);
  std_out[i] = exp(0.5 * logvar);
}
