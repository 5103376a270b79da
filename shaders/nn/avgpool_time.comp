#version 450
// Temporal downsampling of CogVideoXDownsample3D (compress_time): [B, C, F, H, W] -> [B, C, Fo, H, W].
// Odd F: frame 0 is kept and frames 1.. are averaged in pairs (Fo = 1 + (F-1)/2); even F: all frames are
// averaged in pairs (Fo = F/2). A pair average is (a + b) / 2 as avg_pool1d computes it.
// Grid: x over the H*W plane, y = output frame, z = b*C + c (no per-element integer division, which
// lavapipe runs lane by lane).
// Its variant nn/avgpool_time_vec4 (VEC4, shaders/variants.cmake), for planes whose size H*W is a multiple
// of 4, does the same arithmetic on vec4s (a quarter of the memory instructions, which lavapipe runs per lane).
#ifdef VEC4
#define T vec4
#else
#define T float
#endif
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) writeonly buffer Y { T y[]; };

layout(push_constant) uniform Push {
  uint hw;      // H * W (H * W / 4 in the vec4 variant: the plane in elements of x and y)
  uint frames;  // F
  uint frames_out;
  uint bc_begin;  // first b*C + c of this dispatch (grids are split when B*C > 65535)
  uint fo_begin;  // first output frame of this dispatch
  uint x_base, y_base;  // element of x / y at the start of the bound views
} p;

void main() {
  uint s = gl_GlobalInvocationID.x;
  if (s >= p.hw) return;
  uint fo = p.fo_begin + gl_WorkGroupID.y;
  uint bc = p.bc_begin + gl_WorkGroupID.z;
  uint src = bc * p.frames * p.hw + s - p.x_base;
  bool odd = (p.frames & 1u) != 0u;
  T v;
  if (odd && fo == 0u) {
    v = x[src];
  } else {
    uint first = odd ? 2u * fo - 1u : 2u * fo;
    v = (x[src + first * p.hw] + x[src + (first + 1u) * p.hw]) / 2.0;
  }
  y[(bc * p.frames_out + fo) * p.hw + s - p.y_base] = v;
}
