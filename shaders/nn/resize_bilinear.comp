#version 450
// Bilinear resize of planes [P, H, W] -> [P, Ho, Wo] as PyTorch's F.interpolate(mode="bilinear") on CPU:
// source coordinate src = scale·dst (align_corners) or max(scale·(dst + 0.5) - 0.5, 0) (half-pixel), scale
// given in fp32 by the host; i0 = floor(src), i1 = min(i0 + 1, in - 1), lambda = src - i0;
// y = (1-ly)·((1-lx)·x00 + lx·x01) + ly·((1-lx)·x10 + lx·x11).
// Invocation (x, y) writes output column x of rows y, y + rows-stride, ... of this dispatch's output rows
// [first, first + n) of the flattened [P·Ho] rows: the column's taps are computed once, a row's once per row,
// so an output costs its four loads and a few FMAs (no integer division per element).
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint h, w, ho, wo;
  uint first, n;        // output rows (of the flattened [P·Ho] rows) of this dispatch
  uint x_base, y_base;  // element of x / y at the start of the bound views
  float scale_h, scale_w;
  uint align_corners;
} p;

void source(uint dst, uint n_in, float scale, out uint i0, out uint i1, out float l1) {
  float s = p.align_corners != 0u ? scale * float(dst) : max(scale * (float(dst) + 0.5) - 0.5, 0.0);
  i0 = min(uint(s), n_in - 1u);
  i1 = min(i0 + 1u, n_in - 1u);
  l1 = clamp(s - float(i0), 0.0, 1.0);
}

void main() {
  uint col_stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint ox = gl_GlobalInvocationID.x; ox < p.wo; ox += col_stride) {
    uint x0, x1;
    float lx;
    source(ox, p.w, p.scale_w, x0, x1, lx);
    for (uint r = gl_WorkGroupID.y; r < p.n; r += gl_NumWorkGroups.y) {
      uint row = p.first + r, plane = row / p.ho, oy = row - plane * p.ho;
      uint y0, y1;
      float ly;
      source(oy, p.h, p.scale_h, y0, y1, ly);
      uint r0 = (plane * p.h + y0) * p.w - p.x_base, r1 = (plane * p.h + y1) * p.w - p.x_base;
      float top = (1.0 - lx) * x[r0 + x0] + lx * x[r0 + x1];
      float bottom = (1.0 - lx) * x[r1 + x0] + lx * x[r1 + x1];
      y[row * p.wo + ox - p.y_base] = (1.0 - ly) * top + ly * bottom;
    }
  }
}
