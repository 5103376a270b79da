#version 450
#extension GL_GOOGLE_include_directive : require
// Nearest-neighbour resize of video [B, C, F, H, W] -> [B, C, Fo, Ho, Wo] with PyTorch's index rule
// (F.interpolate mode="nearest": src = min(floor(dst * (in / out)), in - 1), the scale in fp32).
// keep_first: frame 0 maps to frame 0 alone and frames 1.. are resized from F-1 to Fo-1, as
// CogVideoXUpsample3D (compress_time, odd F > 1) and CogVideoXSpatialNorm3D do.
layout(local_size_x = 64) in;
#include "index.glsl"  // after local_size: flat_index() reads gl_WorkGroupSize
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint total;  // B * C * Fo * Ho * Wo
  uint frames, h, w;
  uint frames_out, ho, wo;
  uint keep_first;
} p;

uint nearest(uint dst, uint n_in, uint n_out) {
  if (n_in == n_out) return dst;
  if (n_out == 2u * n_in) return dst >> 1;
  float scale = float(n_in) / float(n_out);
  return min(uint(floor(float(dst) * scale)), n_in - 1u);
}

void main() {
  uint i = flat_index();
  if (i >= p.total) return;
  uint ow = i % p.wo;
  uint oh = (i / p.wo) % p.ho;
  uint fo = (i / (p.wo * p.ho)) % p.frames_out;
  uint bc = i / (p.wo * p.ho * p.frames_out);
  uint f;
  if (p.keep_first != 0u) f = fo == 0u ? 0u : 1u + nearest(fo - 1u, p.frames - 1u, p.frames_out - 1u);
  else f = nearest(fo, p.frames, p.frames_out);
  uint ih = nearest(oh, p.h, p.ho), iw = nearest(ow, p.w, p.wo);
  y[i] = x[((bc * p.frames + f) * p.h + ih) * p.w + iw];
}
