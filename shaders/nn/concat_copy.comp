#version 450
#extension GL_GOOGLE_include_directive : require
// nn/concat_copy and its variants (shaders/variants.cmake: _vec4, _tex4): a strided 2-D copy of 32-bit words,
// dst[dst_off + r·dst_stride + k] = src[src_off + r·src_stride + k] for r < rows, k < len.
// Concat copies each input into its column band of the output (viewed as [outer, axis·inner]); split does
// the reverse. VEC4: every size, stride and offset is in units of 4 words; TEXEL: VEC4 reading src through a
// texel buffer.
// Rows loop over the y grid and columns over the x grid (grid-stride both), so no index needs a division
// (a run-time division is scalarised and slow on CPU drivers); short rows (lane_rows) go one whole row per
// invocation over the x grid instead, so lanes are not left idle.
layout(local_size_x = 64) in;
#ifdef VEC4
#define T uvec4
#else
#define T uint
#endif
#ifdef TEXEL
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
layout(binding = 0) uniform utextureBuffer src_tex;  // RGBA32UI: ~2-3x cheaper loads on lavapipe
#define LOAD(j) texelFetch(src_tex, int(j))
#else
layout(std430, binding = 0) readonly buffer Src { T src[]; };
#define LOAD(j) src[j]
#endif
layout(std430, binding = 1) writeonly buffer Dst { T dst[]; };
layout(push_constant) uniform Push {
  uint rows, len, src_stride, src_off, dst_stride, dst_off;
  uint lane_rows;
} p;

void row(uint r, uint k0, uint step) {
  uint s = p.src_off + r * p.src_stride, d = p.dst_off + r * p.dst_stride;
  for (uint k = k0; k < p.len; k += step) dst[d + k] = LOAD(s + k);
}

void main() {
  uint stride_x = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  if (p.lane_rows != 0u) {
    for (uint r = gl_GlobalInvocationID.x; r < p.rows; r += stride_x) row(r, 0u, 1u);
  } else {
    for (uint r = gl_WorkGroupID.y; r < p.rows; r += gl_NumWorkGroups.y) row(r, gl_GlobalInvocationID.x, stride_x);
  }
}
