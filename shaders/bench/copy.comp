#version 450
// Buffer-to-buffer copy through a shader (vec4 loads/stores, grid-stride loop): the device's copy
// bandwidth, the ceiling that memory-bound ops are compared with.
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { vec4 x[]; };
layout(std430, binding = 1) writeonly buffer Out { vec4 y[]; };
layout(push_constant) uniform Push { uint n4; } p;
void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint i = gl_GlobalInvocationID.x; i < p.n4; i += stride) y[i] = x[i];
}
