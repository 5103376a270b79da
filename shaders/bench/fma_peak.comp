#version 450
#extension GL_EXT_control_flow_attributes : require
// The device's fp32 FMA peak: CHAINS independent vec4 FMA chains per invocation, UNROLL rounds per loop trip,
// ITERS rounds in all. Few chains, so that every accumulator stays in a register on a CPU device (lavapipe
// runs 8 invocations per AVX2 register: CHAINS·4 accumulators must fit in its 16 registers) yet enough to
// hide the FMA latency; the unrolled block amortises the per-trip loop-mask work of a SIMD-on-CPU driver.
// One result per invocation keeps the work alive. Drivers differ in which CHAINS x UNROLL they run fastest,
// so the host (bench/harness.cpp) tries a few and keeps the fastest.
layout(local_size_x = 64) in;
layout(constant_id = 0) const int ITERS = 1024;
layout(constant_id = 1) const int CHAINS = 3;
layout(constant_id = 2) const int UNROLL = 32;
layout(std430, binding = 0) writeonly buffer Out { float y[]; };
layout(push_constant) uniform Push { float a; float b; } p;
void main() {
  vec4 v[CHAINS];
  [[unroll]] for (int c = 0; c < CHAINS; ++c) v[c] = vec4(gl_GlobalInvocationID.x + c) * 1e-3;
  for (int it = 0; it < ITERS; it += UNROLL)
    [[unroll]] for (int u = 0; u < UNROLL; ++u)
      [[unroll]] for (int c = 0; c < CHAINS; ++c) v[c] = fma(v[c], vec4(p.a), vec4(p.b));
  vec4 s = vec4(0);
  [[unroll]] for (int c = 0; c < CHAINS; ++c) s += v[c];
  y[gl_GlobalInvocationID.x] = s.x + s.y + s.z + s.w;
}
