// Body of nn/concat_copy and nn/concat_copy_vec4: a strided 2-D copy of 32-bit words,
// dst[dst_off + r·dst_stride + k] = src[src_off + r·src_stride + k] for r < rows, k < len.
// Concat copies each input into its column band of the output (viewed as [outer, axis·inner]); split does
// the reverse. VEC4: every size, stride and offset is in units of 4 words.
layout(local_size_x = 64) in;
#ifdef VEC4
#define T uvec4
#else
#define T uint
#endif
layout(std430, binding = 0) readonly buffer Src { T src[]; };
layout(std430, binding = 1) writeonly buffer Dst { T dst[]; };
layout(push_constant) uniform Push {
  uint n;  // rows · len
  uint len, src_stride, src_off, dst_stride, dst_off;
} p;

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint i = gl_GlobalInvocationID.x; i < p.n; i += stride) {
    uint r = i / p.len, k = i - r * p.len;
    dst[p.dst_off + r * p.dst_stride + k] = src[p.src_off + r * p.src_stride + k];
  }
}
