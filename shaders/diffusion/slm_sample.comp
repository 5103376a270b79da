#version 450
// Stochastic Latent Modulation, the sampling: latent[target_i] = latent[pool[off_s + below(len_s)]] where s is
// target i's segment (its pool: all source elements, those of its frame, or those of its frame and channel)
// and below() is draw element (base + i) of the Philox stream (seed, stream), bit-identical to
// philox::below in engine/src/tensor/philox.hpp. Targets and pool are disjoint, so reading and writing the
// same latent in one dispatch has no race.
#extension GL_GOOGLE_include_directive : require
#include "philox.glsl"

layout(local_size_x = 64) in;
#include "index.glsl"

layout(std430, binding = 0) buffer Latent { float latent[]; };
layout(std430, binding = 1) readonly buffer Targets { ivec2 targets[]; };    // (element, segment)
layout(std430, binding = 2) readonly buffer Segments { ivec2 segments[]; };  // (pool offset, length >= 1)
layout(std430, binding = 3) readonly buffer Pool { int pool[]; };            // source element indices
layout(push_constant) uniform Push {
  uint n_targets;
  uint seed_lo, seed_hi;
  uint stream;
  uint base_lo, base_hi;
} p;

const uint kMaxRetries = 64u;  // as philox::kMaxRetries

void main() {
  uint i = flat_index();
  if (i >= p.n_targets) return;
  ivec2 t = targets[i];
  ivec2 seg = segments[t.y];
  uint n = uint(seg.y);

  uint carry;
  uint e_lo = uaddCarry(p.base_lo, i, carry);
  uint e_hi = p.base_hi + carry;
  uint word = e_lo & 3u;
  uvec4 ctr = uvec4((e_lo >> 2) | (e_hi << 30), e_hi >> 2, p.stream, 0u);
  uvec2 key = uvec2(p.seed_lo, p.seed_hi);

  uint threshold = (0u - n) % n;  // 2^32 mod n
  uint hi, lo;
  umulExtended(philox4x32_10(ctr, key)[word], n, hi, lo);
  for (uint retry = 1u; retry <= kMaxRetries && lo < threshold; ++retry) {
    ctr.w = retry;
    umulExtended(philox4x32_10(ctr, key)[word], n, hi, lo);
  }
  latent[t.x] = latent[pool[seg.x + int(hi)]];
}
