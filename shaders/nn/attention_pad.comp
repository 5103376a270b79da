#version 450
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
#extension GL_GOOGLE_include_directive : require
// Attention for a head_dim D that is not a multiple of 4 (attention.comp reads whole vec4s per head): copies
// the heads of token-major rows between the models' layout (D columns per head, any column offset and row
// stride, in elements) and a head-padded one (Dp = D rounded up to 4 columns per head, zeros in the padded
// columns, which add nothing to q·k nor to p·v). pad = 1: model layout -> padded (q, k, v before the
// attention); pad = 0: padded -> model layout, the first D columns of each head (the output after it).
// One invocation per element written; a dispatch covers `rows` token rows of `heads` heads (ops_attention.cpp
// cuts the copies into chunks that fit one binding and one grid).
layout(local_size_x = 64) in;
// After the local size: flat_index() uses gl_WorkGroupSize, which is (1,1,1) until the layout is declared.
#include "index.glsl"

layout(binding = 0) uniform textureBuffer Src;  // R32F
layout(std430, binding = 1) writeonly buffer Dst { float dst[]; };

layout(push_constant) uniform Push {
  uint count;                       // elements written: rows · heads · (pad ? dp : d)
  uint heads, d, dp, pad;
  uint src_off, src_stride;         // elements: row r, head h, column c at src_off + r·src_stride + h·(pad ? d : dp) + c
  uint dst_off, dst_stride;         // elements: row r, head h, column c at dst_off + r·dst_stride + h·(pad ? dp : d) + c
} p;

void main() {
  const uint i = flat_index();
  if (i >= p.count) return;
  const bool pad = p.pad != 0;
  const uint w = pad ? p.dp : p.d;  // columns per head written
  const uint c = i % w, rest = i / w;
  const uint h = rest % p.heads, r = rest / p.heads;
  const uint src_w = pad ? p.d : p.dp;
  float x = 0.0;
  if (c < p.d) x = texelFetch(Src, int(p.src_off + r * p.src_stride + h * src_w + c)).x;
  dst[p.dst_off + r * p.dst_stride + h * w + c] = x;
}
