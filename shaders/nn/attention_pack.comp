#version 450
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
#extension GL_GOOGLE_include_directive : require
// Repacks K and V from the models' token-major [B, L, H·D] rows (any row stride and column offset) into
// head-major [B, H, L, D] in the attention workspace, so that attention streams each head's keys from
// contiguous memory. One invocation per vec4; gl_WorkGroupID.z picks K (0) or V (1). A dispatch may cover
// only `rows` token rows of a group of heads (its outputs bound from the first key written): the split path
// repacks a long sequence in chunks that each fit one binding.
layout(local_size_x = 64) in;
// After the local size: flat_index() uses gl_WorkGroupSize, which is (1,1,1) until the layout is declared.
#include "index.glsl"

layout(binding = 0) uniform textureBuffer K;  // RGBA32F
layout(binding = 1) uniform textureBuffer V;  // RGBA32F
layout(std430, binding = 2) writeonly buffer PackedK { vec4 pk[]; };
layout(std430, binding = 3) writeonly buffer PackedV { vec4 pv[]; };

layout(push_constant) uniform Push {
  uint count;  // vec4s per tensor in this dispatch: B·H·rows·D4
  uint rows, heads, d4;
  uint k_off, k_stride, v_off, v_stride;  // input rows, vec4 units
  uint out_len;                           // output keys per head
  uint pk_off, pv_off;                    // vec4 units
} p;

void main() {
  const uint i = flat_index();
  if (i >= p.count) return;
  uint c = i % p.d4, rest = i / p.d4;
  uint l = rest % p.rows;
  rest /= p.rows;
  uint h = rest % p.heads, b = rest / p.heads;
  uint row = b * p.rows + l;
  uint o = ((b * p.heads + h) * p.out_len + l) * p.d4 + c;
  if (gl_WorkGroupID.z == 0)
    pk[p.pk_off + o] = texelFetch(K, int(row * p.k_stride + p.k_off + h * p.d4 + c));
  else
    pv[p.pv_off + o] = texelFetch(V, int(row * p.v_stride + p.v_off + h * p.d4 + c));
}
