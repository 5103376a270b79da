#version 450
#extension GL_EXT_control_flow_attributes : require
// The device's fp32 FMA peak: CHAINS independent vec4 FMA chains per invocation for ITERS rounds (many
// chains amortise the loop and hide FMA latency on GPUs and on lavapipe's SIMD lanes); one result per
// invocation keeps the work alive.
layout(local_size_x = 64) in;
layout(constant_id = 0) const int ITERS = 1024;
const int CHAINS = 16;
layout(std430, binding = 0) writeonly buffer Out { float y[]; };
layout(push_constant) uniform Push { float a; float b; } p;
void main() {
  vec4 v[CHAINS];
  for (int c = 0; c < CHAINS; ++c) v[c] = vec4(gl_GlobalInvocationID.x + c) * 1e-3;
  for (int it = 0; it < ITERS; ++it)
    [[unroll]] for (int c = 0; c < CHAINS; ++c) v[c] = fma(v[c], vec4(p.a), vec4(p.b));
  vec4 s = vec4(0);
  for (int c = 0; c < CHAINS; ++c) s += v[c];
  y[gl_GlobalInvocationID.x] = s.x + s.y + s.z + s.w;
}
