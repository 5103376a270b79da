#version 450
// Pass 1 of the soft splat: the frame's max over all points of log(1 + clamp(z2, 0, 1000)) (z2 = target
// depth), stored as float bits (non-negative floats order like their bits; framemax starts at 0). Each
// invocation takes RUN consecutive pixels of a row and issues one atomicMax (no shared memory or barriers:
// both are slow on CPU drivers); log is monotonic, so the max is taken on clamp(z2) and logged once.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) buffer FrameMax { uint framemax[]; };
#include "splat_common.glsl"

const uint RUN = 16u;  // the host dispatches div_up(W, 64·RUN) groups in x

void main() {
  const uint y = gl_WorkGroupID.y;
  const uint x0 = gl_GlobalInvocationID.x * RUN;
  float m = 0.0;
  for (uint x = x0; x < min(x0 + RUN, p.W); ++x) {
    vec3 X2 = move_point(x, y, depth[(p.frame * p.H + y) * p.W + x]).X2;
    if (point_used(X2)) m = max(m, clamp(X2.z, 0.0, 1000.0));
  }
  if (m > 0.0) atomicMax(framemax[p.frame], floatBitsToUint(log_depth(m)));
}
