#version 450
#extension GL_GOOGLE_include_directive : require
// Temporal downsampling of CogVideoXDownsample3D (compress_time): [B, C, F, H, W] -> [B, C, Fo, H, W].
// Odd F: frame 0 is kept and frames 1.. are averaged in pairs (Fo = 1 + (F-1)/2); even F: all frames are
// averaged in pairs (Fo = F/2). A pair average is (a + b) / 2 as avg_pool1d computes it.
layout(local_size_x = 64) in;
#include "index.glsl"  // after local_size: flat_index() reads gl_WorkGroupSize
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint total;   // B * C * Fo * H * W
  uint hw;      // H * W
  uint frames;  // F
  uint frames_out;
} p;

void main() {
  uint i = flat_index();
  if (i >= p.total) return;
  uint s = i % p.hw;
  uint fo = (i / p.hw) % p.frames_out;
  uint bc = i / (p.hw * p.frames_out);
  uint src = bc * p.frames * p.hw + s;
  bool odd = (p.frames & 1u) != 0u;
  float v;
  if (odd && fo == 0u) {
    v = x[src];
  } else {
    uint first = odd ? 2u * fo - 1u : 2u * fo;
    v = (x[src + first * p.hw] + x[src + (first + 1u) * p.hw]) / 2.0;
  }
  y[i] = v;
}
