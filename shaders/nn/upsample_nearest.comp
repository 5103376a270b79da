#version 450
// Nearest-neighbour resize of video [B, C, F, H, W] -> [B, C, Fo, Ho, Wo] with PyTorch's index rule
// (F.interpolate mode="nearest": src = min(floor(dst * (in / out)), in - 1), the scale in fp32).
// keep_first: frame 0 maps to frame 0 alone and frames 1.. are resized from F-1 to Fo-1, as
// CogVideoXUpsample3D (compress_time, odd F > 1) and CogVideoXSpatialNorm3D do.
// Grid: x over output columns, y = output row, z = (b*C + c) * Fo + output frame.
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint frames, h, w;
  uint frames_out, ho, wo;
  uint keep_first;
  uint z_begin;    // first z of this dispatch
  uint row_begin;  // first output row of this dispatch
  uint x_base, y_base;  // element of x / y at the start of the bound views
} p;

uint nearest(uint dst, uint n_in, uint n_out) {
  if (n_in == n_out) return dst;
  if (n_out == 2u * n_in) return dst >> 1;
  float scale = float(n_in) / float(n_out);
  return min(uint(floor(float(dst) * scale)), n_in - 1u);
}

void main() {
  uint ow = gl_GlobalInvocationID.x;
  if (ow >= p.wo) return;
  uint oh = p.row_begin + gl_WorkGroupID.y;
  uint z = p.z_begin + gl_WorkGroupID.z;
  uint fo = z % p.frames_out;
  uint bc = z / p.frames_out;
  uint f;
  if (p.keep_first != 0u) f = fo == 0u ? 0u : 1u + nearest(fo - 1u, p.frames - 1u, p.frames_out - 1u);
  else f = nearest(fo, p.frames, p.frames_out);
  uint src_row = ((bc * p.frames + f) * p.h + nearest(oh, p.h, p.ho)) * p.w;
  y[(z * p.ho + oh) * p.wo + ow - p.y_base] = x[src_row + nearest(ow, p.w, p.wo) - p.x_base];
}
