#version 450
// Nearest x2 spatial upsampling of video [B, C, F, H, W] -> [B, C, Fo, 2H, 2W] with a frame map given
// by the host rule (CogVideoXUpsample3D): keep_first (odd F > 1 with compress_time): output frame 0 <-
// frame 0, output frame t > 0 <- 1 + (t-1)/2; double (even F with compress_time): t <- t/2; else t <- t.
// One invocation per input pixel: one load, two 2-wide stores (rows 2i and 2i+1), which beats the
// general resize (one load and one store per output element) on drivers that run memory ops per lane.
// Grid: x over input columns, y = input row, z = (b*C + c) * Fo + output frame.
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { vec2 y[]; };  // output rows have 2W (even) elements

layout(push_constant) uniform Push {
  uint frames, h, w;
  uint frames_out;
  uint time_mode;  // 0: same frame, 1: keep_first, 2: double
  uint z_begin;    // first z of this dispatch
  uint row_begin;  // first input row of this dispatch
  uint x_base, y_base;  // float of x / vec2 of y at the start of the bound views
} p;

void main() {
  uint iw = gl_GlobalInvocationID.x;
  if (iw >= p.w) return;
  uint ih = p.row_begin + gl_WorkGroupID.y;
  uint z = p.z_begin + gl_WorkGroupID.z;
  uint fo = z % p.frames_out;
  uint bc = z / p.frames_out;
  uint f = p.time_mode == 0u ? fo : (p.time_mode == 1u ? (fo == 0u ? 0u : 1u + ((fo - 1u) >> 1)) : fo >> 1);
  float v = x[((bc * p.frames + f) * p.h + ih) * p.w + iw - p.x_base];
  uint row0 = (z * 2u * p.h + 2u * ih) * p.w - p.y_base;  // in vec2 units: a row of 2W floats is W vec2
  y[row0 + iw] = vec2(v);
  y[row0 + p.w + iw] = vec2(v);
}
