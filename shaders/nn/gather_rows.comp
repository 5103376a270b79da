#version 450
#extension GL_GOOGLE_include_directive : require
// nn/gather_rows and its variant nn/gather_rows_vec4 (VEC4, shaders/variants.cmake): moves m rows of `len`
// 32-bit words, dst[dst_row(i)] = src[src_row(i)] with src_row(i) = src_idx[i] (or i) and dst_row(i) = dst_idx[i] (or i).
// Gather: src_idx only; scatter: dst_idx only; both: SLM's target[t[i]] = source[s[i]] in one pass.
// A source index outside [0, src_rows) reads zeros; a destination index outside [0, dst_rows) is skipped.
// Duplicate destination indices: one of the writes wins (unspecified which).
// A split call binds an indexed table (src with src_idx, dst with dst_idx) in row ranges: this dispatch holds
// rows [first, first + rows) of `total`; indices elsewhere in the table are left to the other dispatches, and
// the zero rows of out-of-table source indices are written by the dispatch holding row 0.
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
  uint src_first, src_total, dst_first, dst_total;  // the bound row range of an indexed table
} p;

void move_row(uint r, uint k0, uint step) {
  uint s = r, d = r;
  bool zero = false;
  if (p.use_src_idx != 0u) {
    s = uint(src_idx[r]);  // negative -> huge -> out of range
    if (s >= p.src_total) {
      if (p.src_first != 0u) return;
      zero = true;
    } else {
      s -= p.src_first;  // below the range -> huge
      if (s >= p.src_rows) return;
    }
  }
  if (p.use_dst_idx != 0u) {
    d = uint(dst_idx[r]) - p.dst_first;
    if (uint(dst_idx[r]) >= p.dst_total || d >= p.dst_rows) return;
  }
  for (uint k = k0; k < p.len; k += step) dst[d * p.len + k] = zero ? T(0u) : src[s * p.len + k];
}

void main() {
  uint stride_x = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  if (p.lane_rows != 0u) {
    for (uint r = gl_GlobalInvocationID.x; r < p.m; r += stride_x) move_row(r, 0u, 1u);
  } else {
    for (uint r = gl_WorkGroupID.y; r < p.m; r += gl_NumWorkGroups.y) move_row(r, gl_GlobalInvocationID.x, stride_x);
  }
}
