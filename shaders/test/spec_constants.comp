#version 450
// Runtime probe for tests: out[i] = in[i] * SCALE + OFFSET + push.bias, with SCALE/OFFSET specialization
// constants, so a test sees that constants, push constants and bindings all arrive.
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const float SCALE = 1.0;
layout(constant_id = 2) const int OFFSET = 0;

layout(std430, binding = 0) readonly buffer In { float x[]; };
layout(std430, binding = 1) writeonly buffer Out { float y[]; };
layout(push_constant) uniform Push { uint n; float bias; } p;

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i < p.n) y[i] = x[i] * SCALE + float(OFFSET) + p.bias;
}
