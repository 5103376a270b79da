// Body of nn/permute and nn/permute_vec4: out[c0..c5] = in[Σ c_d · in_stride[d]] for 32-bit words, rank ≤ 6
// after the host merged axes that stay adjacent (so [B,F,C,H,W] -> [B,C,F,H,W] runs as [B,F,C,HW] ->
// [B,C,F,HW]). VEC4: the innermost axis is contiguous in both tensors and counted in units of 4 words.
layout(local_size_x = 64) in;
#ifdef VEC4
#define T uvec4
#else
#define T uint
#endif
layout(std430, binding = 0) readonly buffer In { T x[]; };
layout(std430, binding = 1) writeonly buffer Out { T y[]; };
layout(push_constant) uniform Push {
  uint n, rank;
  uint dims[6];        // output dims, outermost first (unused trailing entries 1)
  uint in_stride[6];   // input stride of the axis that lands on output axis d
} p;

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint i = gl_GlobalInvocationID.x; i < p.n; i += stride) {
    uint rest = i, off = 0u;
    for (int d = int(p.rank) - 1; d >= 0; --d) {
      uint c = rest % p.dims[d];
      rest /= p.dims[d];
      off += c * p.in_stride[d];
    }
    y[i] = x[off];
  }
}
