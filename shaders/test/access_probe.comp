#version 450
#extension GL_EXT_samplerless_texture_functions : require
// Probe for the recorder's barrier tests (tests/test_recorder_barriers.cpp): y[i] = x[i] + 1 for i < n, reading
// x through one kind of binding and writing y through the matching kind, so a test can make one command read
// or write a buffer range as a storage buffer (default), a uniform texel buffer (UNIFORM_TEXEL: x only; y stays a
// storage buffer) or a storage texel buffer (STORAGE_TEXEL: both, r32f).
layout(local_size_x = 64) in;
layout(push_constant) uniform Push { uint n; } p;

#if defined(UNIFORM_TEXEL)
layout(binding = 0) uniform textureBuffer x;
float load_x(uint i) { return texelFetch(x, int(i)).r; }
#elif defined(STORAGE_TEXEL)
layout(binding = 0, r32f) readonly uniform imageBuffer x;
float load_x(uint i) { return imageLoad(x, int(i)).r; }
#else
layout(std430, binding = 0) readonly buffer X { float x[]; };
float load_x(uint i) { return x[i]; }
#endif

#if defined(STORAGE_TEXEL)
layout(binding = 1, r32f) writeonly uniform imageBuffer y;
void store_y(uint i, float v) { imageStore(y, int(i), vec4(v)); }
#else
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
void store_y(uint i, float v) { y[i] = v; }
#endif

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i < p.n) store_y(i, load_x(i) + 1.0);
}
