// Body of nn/gather_rows and nn/gather_rows_vec4: moves m rows of `len` 32-bit words,
// dst[dst_row(i)] = src[src_row(i)] with src_row(i) = src_idx[i] (or i) and dst_row(i) = dst_idx[i] (or i).
// Gather: src_idx only; scatter: dst_idx only; both: SLM's target[t[i]] = source[s[i]] in one pass.
// A source index outside [0, src_rows) reads zeros; a destination index outside [0, dst_rows) is skipped.
// Duplicate destination indices: one of the writes wins (unspecified which).
// Index rows over the y grid, words of a row over x (grid-stride both): no per-element division. Short rows
// (lane_rows): one whole row per invocation over the x grid, so lanes are not left idle.
layout(local_size_x = 64) in;
#ifdef VEC4
#define T uvec4
#else
#define T uint
#endif
layout(std430, binding = 0) readonly buffer Src { T src[]; };
layout(std430, binding = 1) readonly buffer SrcIdx { int src_idx[]; };
layout(std430, binding = 2) readonly buffer DstIdx { int dst_idx[]; };
layout(std430, binding = 3) writeonly buffer Dst { T dst[]; };
layout(push_constant) uniform Push {
  uint m;    // index rows
  uint len;  // row length in units of T
  uint src_rows, dst_rows;
  uint use_src_idx, use_dst_idx;
  uint lane_rows;
} p;

void move_row(uint r, uint k0, uint step) {
  uint s = p.use_src_idx != 0u ? uint(src_idx[r]) : r;  // negative -> huge -> out of range
  uint d = p.use_dst_idx != 0u ? uint(dst_idx[r]) : r;
  if (d >= p.dst_rows) return;
  for (uint k = k0; k < p.len; k += step) dst[d * p.len + k] = s < p.src_rows ? src[s * p.len + k] : T(0u);
}

void main() {
  uint stride_x = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  if (p.lane_rows != 0u) {
    for (uint r = gl_GlobalInvocationID.x; r < p.m; r += stride_x) move_row(r, 0u, 1u);
  } else {
    for (uint r = gl_WorkGroupID.y; r < p.m; r += gl_NumWorkGroups.y) move_row(r, gl_GlobalInvocationID.x, stride_x);
  }
}
