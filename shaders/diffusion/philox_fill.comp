#version 450
// Fills a tensor with counter-based random numbers: element i of the output is element (base + i) of the
// draw (seed, stream), see engine/src/tensor/philox.hpp. One invocation per Philox block of 4 elements.
// DIST 0: uniform f32 in [0, 1) scaled to [lo, hi); 1: normal f32 (mean, std); 2: uniform i32 in [0, n).
#extension GL_GOOGLE_include_directive : require
#include "philox.glsl"

layout(constant_id = 0) const uint DIST = 0;
layout(local_size_x = 64) in;
layout(std430, binding = 0) writeonly buffer Out { uint y[]; };
layout(push_constant) uniform Push {
  uint n;                // elements to write
  uint skew;             // base % 4: words of the first block that precede the output
  uint n_blocks;         // ceil((skew + n) / 4)
  uint first_block_lo, first_block_hi;  // base / 4
  uint seed_lo, seed_hi;
  uint stream;
  float a, b;            // uniform: lo, hi; normal: mean, std
  uint range;            // integers: n of [0, n)
} p;

const uint kMaxRetries = 64u;  // as philox::kMaxRetries

uint below(uvec4 ctr, uvec2 key, uint word, uint x) {
  uint threshold = (0u - p.range) % p.range;  // 2^32 mod n
  uint hi, lo;
  umulExtended(x, p.range, hi, lo);
  for (uint retry = 1u; retry <= kMaxRetries && lo < threshold; ++retry) {
    ctr.w = retry;
    uvec4 r = philox4x32_10(ctr, key);
    umulExtended(r[word], p.range, hi, lo);
  }
  return hi;
}

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uvec2 key = uvec2(p.seed_lo, p.seed_hi);
  for (uint j = gl_GlobalInvocationID.x; j < p.n_blocks; j += stride) {
    uint carry;
    uint blo = uaddCarry(p.first_block_lo, j, carry);
    uvec4 ctr = uvec4(blo, p.first_block_hi + carry, p.stream, 0u);
    uvec4 r = philox4x32_10(ctr, key);
    uvec4 out_bits;
    if (DIST == 0u) {
      vec4 u = vec4(philox_uniform(r.x), philox_uniform(r.y), philox_uniform(r.z), philox_uniform(r.w));
      precise vec4 v = p.a + (p.b - p.a) * u;  // no fused multiply-add: matches the host formula
      out_bits = floatBitsToUint(v);
    } else if (DIST == 1u) {
      vec4 g = vec4(philox_box_muller(r.x, r.y), philox_box_muller(r.z, r.w));
      precise vec4 v = p.a + p.b * g;  // no fused multiply-add: mean + std·z as on the host
      out_bits = floatBitsToUint(v);
    } else {
      for (uint w = 0u; w < 4u; ++w) out_bits[w] = below(ctr, key, w, r[w]);
    }
    for (uint w = 0u; w < 4u; ++w) {
      uint e = j * 4u + w;  // position within the block range
      if (e >= p.skew && e - p.skew < p.n) y[e - p.skew] = out_bits[w];
    }
  }
}
