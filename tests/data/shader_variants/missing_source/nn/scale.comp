#version 450
layout(local_size_x = 64) in;
#ifdef VEC4
layout(std430, binding = 0) buffer X { vec4 x[]; };
#else
layout(std430, binding = 0) buffer X { float x[]; };
#endif
void main() { x[gl_GlobalInvocationID.x] *= 2.0; }
