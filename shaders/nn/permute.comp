#version 450
#extension GL_GOOGLE_include_directive : require
// nn/permute and its variants _vec4 and _tex4 (shaders/variants.cmake): out[c0..c5] = in[Σ c_d · in_stride[d]]
// for 32-bit words, rank ≤ 6 after the host merged axes that stay adjacent (so [B,F,C,H,W] -> [B,C,F,H,W]
// runs as [B,F,C,HW] -> [B,C,F,HW]). One output row (the last axis) per y step, its elements over x: the coordinates are decomposed
// (run-time divisions, slow on CPU drivers) once per row, not per element. Short rows (lane_rows): one whole
// row per invocation over the x grid, so lanes are not left idle.
// VEC4: the innermost axis is contiguous in both tensors and counted in units of 4 words; TEXEL: VEC4 reading
// the input through a texel buffer.
layout(local_size_x = 64) in;
#ifdef VEC4
#define T uvec4
#else
#define T uint
#endif
#ifdef TEXEL
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
layout(binding = 0) uniform utextureBuffer x_tex;  // RGBA32UI: ~2-3x cheaper loads on lavapipe
#define LOAD(j) texelFetch(x_tex, int(j))
#else
layout(std430, binding = 0) readonly buffer In { T x[]; };
#define LOAD(j) x[j]
#endif
layout(std430, binding = 1) writeonly buffer Out { T y[]; };
layout(push_constant) uniform Push {
  uint rows, rank;     // rows = product of all output dims but the last
  uint dims[6];        // output dims, outermost first (unused trailing entries 1)
  uint in_stride[6];   // input stride of the axis that lands on output axis d
  uint lane_rows;
  uint in_off, out_off;  // where the chunk starts in the bound input and output windows (split calls)
} p;

void copy_row(uint row, uint k0, uint step) {
  uint last = p.dims[p.rank - 1u], last_stride = p.in_stride[p.rank - 1u];
  uint rest = row, base = p.in_off;
  for (int d = int(p.rank) - 2; d >= 0; --d) {
    uint c = rest % p.dims[d];
    rest /= p.dims[d];
    base += c * p.in_stride[d];
  }
  for (uint k = k0; k < last; k += step) y[p.out_off + row * last + k] = LOAD(base + k * last_stride);
}

void main() {
  uint stride_x = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  if (p.lane_rows != 0u) {
    for (uint row = gl_GlobalInvocationID.x; row < p.rows; row += stride_x) copy_row(row, 0u, 1u);
  } else {
    for (uint row = gl_WorkGroupID.y; row < p.rows; row += gl_NumWorkGroups.y)
      copy_row(row, gl_GlobalInvocationID.x, stride_x);
  }
}
