#version 450
// Stochastic Latent Modulation, step 1 of the background mask: the largest disparity of each pixel frame
// (disparity = the input, or 1/z for metric depth; z <= 0 or NaN counts as disparity 0). One workgroup per
// frame; max is exact, so the result does not depend on the reduction order.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };  // [frames, H, W] from first_frame
layout(std430, binding = 1) writeonly buffer FrameMax { float frame_max[]; };  // [Fp]
layout(push_constant) uniform Push {
  uint frames;
  uint pixels;  // H·W
  uint metric;  // 1: depth holds metric z, disparity = 1/z
  uint first_frame;  // depth is bound from this frame on (clips over one binding run in frame windows)
} p;

shared float partial[256];

float disparity(float x) {
  if (p.metric != 0u) return x > 0.0 ? 1.0 / x : 0.0;
  return x > 0.0 ? x : 0.0;  // negative or NaN disparity: treated as 0 (infinitely far)
}

void main() {
  uint f = gl_WorkGroupID.x;
  if (f >= p.frames) return;
  uint base = f * p.pixels;
  float m = 0.0;
  for (uint i = gl_LocalInvocationID.x; i < p.pixels; i += 256u) m = max(m, disparity(depth[base + i]));
  partial[gl_LocalInvocationID.x] = m;
  barrier();
  for (uint s = 128u; s > 0u; s >>= 1) {
    if (gl_LocalInvocationID.x < s)
      partial[gl_LocalInvocationID.x] = max(partial[gl_LocalInvocationID.x], partial[gl_LocalInvocationID.x + s]);
    barrier();
  }
  if (gl_LocalInvocationID.x == 0u) frame_max[p.first_frame + f] = partial[0];
}
