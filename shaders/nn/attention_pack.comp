#version 450
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
#extension GL_GOOGLE_include_directive : require
// Repacks K and V from the models' token-major [B, L, H·D] rows (any row stride and column offset) into
// head-major [B, H, L, D] in the attention workspace (K first, then V), so that attention streams each head's
// keys from contiguous memory. One invocation per vec4; gl_WorkGroupID.z picks K (0) or V (1).
layout(local_size_x = 64) in;
// After the local size: flat_index() uses gl_WorkGroupSize, which is (1,1,1) until the layout is declared.
#include "index.glsl"

layout(binding = 0) uniform textureBuffer K;  // RGBA32F
layout(binding = 1) uniform textureBuffer V;  // RGBA32F
layout(std430, binding = 2) writeonly buffer Packed { vec4 packed[]; };

layout(push_constant) uniform Push {
  uint count;  // vec4s per tensor: B·H·L·D4
  uint kv_len, heads, d4;
  uint k_off, k_stride, v_off, v_stride;  // vec4 units
} p;

void main() {
  const uint i = flat_index();
  if (i >= p.count) return;
  uint c = i % p.d4, rest = i / p.d4;
  uint l = rest % p.kv_len;
  rest /= p.kv_len;
  uint h = rest % p.heads, b = rest / p.heads;
  uint row = b * p.kv_len + l;
  if (gl_WorkGroupID.z == 0)
    packed[i] = texelFetch(K, int(row * p.k_stride + p.k_off + h * p.d4 + c));
  else
    packed[p.count + i] = texelFetch(V, int(row * p.v_stride + p.v_off + h * p.d4 + c));
}
