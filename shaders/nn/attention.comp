#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Flash attention: out = softmax(q·kᵀ·scale + bias + mask)·v, one (batch, head, block of query rows) per
// workgroup, keys streamed in blocks with an online softmax in fp32 (running max and sum per row), so no
// Lq×Lk matrix ever exists.
//
// Work split (built for lavapipe, where every memory load is a per-lane loop but a broadcast from a
// constant lane is one shuffle): a "team" of 8 lanes owns R query rows.
//   scores:  lane L owns keys L, L+8, ... of the block (KC of them) and reads their K rows itself
//            (texel fetches); the q values are broadcast from the lane that holds them.
//   p·v:     lane L owns columns 4L..4L+3, 32+4L.. of the head (DC vec4 chunks) and reads those of V;
//            each probability is broadcast from the lane that owns its key.
// Teams are 8 lanes whatever the subgroup size (8 on lavapipe, 32/64 on GPUs): with NATIVE8 the team is
// the subgroup and broadcasts use constant lanes; otherwise clustered shuffles.
//
// Masked keys get the logit -FLT_MAX (what transformers' finfo.min mask amounts to in fp32): they weigh
// exp(-huge) = 0 unless every key of a row is masked, in which case all logits are equal and the row is the
// mean of v over all Lk keys, as in transformers.
layout(local_size_x = 64) in;

layout(constant_id = 0) const int D4 = 16;            // head_dim / 4
layout(constant_id = 1) const bool HAS_BIAS = false;  // additive bias [H, Lq, Lk]
layout(constant_id = 2) const bool HAS_MASK = false;  // key mask [B, Lk], 0 = masked
layout(constant_id = 3) const bool NATIVE8 = true;    // subgroup size is 8: team == subgroup

const int TEAM = 8;
const int DC = (D4 + TEAM - 1) / TEAM;  // vec4 chunks of a head row per lane
const int R = 4;                         // query rows per team
const int KC = 4;                        // keys per lane per block
const int KB = KC * TEAM;                // keys per block
const int TEAMS = int(gl_WorkGroupSize.x) / TEAM;
const float LOG2E = 1.4426950408889634;
const float MASKED = -3.4028234663852886e38;  // -FLT_MAX

layout(binding = 0) uniform samplerBuffer Q;  // RGBA32F texels
layout(binding = 1) uniform samplerBuffer K;
layout(binding = 2) uniform samplerBuffer V;
layout(std430, binding = 3) writeonly buffer Out { vec4 o[]; };
layout(std430, binding = 4) readonly buffer Bias { float bias[]; };
layout(std430, binding = 5) readonly buffer Mask { float key_mask[]; };

// Offsets and strides of q, k, v, out in vec4 units.
layout(push_constant) uniform Push {
  uint q_len, kv_len, heads;
  uint q_off, q_stride, k_off, k_stride, v_off, v_stride, o_off, o_stride;
  float scale;
} p;

uint lane, team_base;

#define BCAST(x, L) (NATIVE8 ? subgroupBroadcast(x, L) : subgroupShuffle(x, team_base + L))

float team_max(float x) {
  if (NATIVE8) return subgroupMax(x);
  x = max(x, subgroupShuffleXor(x, 1));
  x = max(x, subgroupShuffleXor(x, 2));
  return max(x, subgroupShuffleXor(x, 4));
}

float team_sum(float x) {
  if (NATIVE8) return subgroupAdd(x);
  x += subgroupShuffleXor(x, 1);
  x += subgroupShuffleXor(x, 2);
  return x + subgroupShuffleXor(x, 4);
}

void main() {
  lane = gl_SubgroupInvocationID % TEAM;
  team_base = gl_SubgroupInvocationID - lane;
  const uint team = gl_SubgroupID * (gl_SubgroupSize / TEAM) + gl_SubgroupInvocationID / TEAM;
  const uint h = gl_WorkGroupID.y, b = gl_WorkGroupID.z;
  const uint row0 = (gl_WorkGroupID.x * TEAMS + team) * R;
  if (row0 >= p.q_len) return;  // whole team idle (uniform within the team)

  // This lane's q chunks, pre-multiplied by scale·log2(e) so that scores are in the exp2 domain.
  vec4 qreg[R][DC];
  [[unroll]] for (int r = 0; r < R; ++r) {
    uint row = min(row0 + r, p.q_len - 1);
    uint base = (b * p.q_len + row) * p.q_stride + p.q_off + h * D4;
    [[unroll]] for (int s = 0; s < DC; ++s) {
      uint c = s * TEAM + lane;
      qreg[r][s] = c < D4 ? texelFetch(Q, int(base + c)) * (p.scale * LOG2E) : vec4(0);
    }
  }

  float m[R], l[R];
  vec4 acc[R][DC];
  [[unroll]] for (int r = 0; r < R; ++r) {
    m[r] = MASKED;
    l[r] = 0;
    [[unroll]] for (int s = 0; s < DC; ++s) acc[r][s] = vec4(0);
  }

  const uint kv_row0 = b * p.kv_len;
  for (uint key0 = 0; key0 < p.kv_len; key0 += KB) {
    // ---- scores for my KC keys ----
    uint kaddr[KC];
    bool valid[KC];
    [[unroll]] for (int kc = 0; kc < KC; ++kc) {
      uint key = key0 + kc * TEAM + lane;
      valid[kc] = key < p.kv_len;
      kaddr[kc] = (kv_row0 + min(key, p.kv_len - 1)) * p.k_stride + p.k_off + h * D4;
    }
    float sc[R][KC];
    [[unroll]] for (int r = 0; r < R; ++r)
      [[unroll]] for (int kc = 0; kc < KC; ++kc) sc[r][kc] = 0;

#define SCORE_CHUNKS_FROM_LANE(L)                                                \
    [[unroll]] for (int s = 0; s < DC; ++s) {                                    \
      int c = s * TEAM + L;                                                      \
      if (c < D4) {                                                              \
        vec4 kv[KC];                                                             \
        [[unroll]] for (int kc = 0; kc < KC; ++kc) kv[kc] = texelFetch(K, int(kaddr[kc] + c)); \
        [[unroll]] for (int r = 0; r < R; ++r) {                                 \
          vec4 qv = BCAST(qreg[r][s], L);                                        \
          [[unroll]] for (int kc = 0; kc < KC; ++kc) sc[r][kc] += dot(qv, kv[kc]); \
        }                                                                        \
      }                                                                          \
    }
    SCORE_CHUNKS_FROM_LANE(0)
    SCORE_CHUNKS_FROM_LANE(1)
    SCORE_CHUNKS_FROM_LANE(2)
    SCORE_CHUNKS_FROM_LANE(3)
    SCORE_CHUNKS_FROM_LANE(4)
    SCORE_CHUNKS_FROM_LANE(5)
    SCORE_CHUNKS_FROM_LANE(6)
    SCORE_CHUNKS_FROM_LANE(7)

    if (HAS_BIAS) {
      [[unroll]] for (int r = 0; r < R; ++r) {
        uint row = min(row0 + r, p.q_len - 1);
        uint base = (h * p.q_len + row) * p.kv_len;
        [[unroll]] for (int kc = 0; kc < KC; ++kc)
          sc[r][kc] += bias[base + min(key0 + kc * TEAM + lane, p.kv_len - 1)] * LOG2E;
      }
    }
    if (HAS_MASK) {
      [[unroll]] for (int kc = 0; kc < KC; ++kc) {
        bool masked = key_mask[kv_row0 + min(key0 + kc * TEAM + lane, p.kv_len - 1)] == 0.0;
        if (masked) {
          [[unroll]] for (int r = 0; r < R; ++r) sc[r][kc] = MASKED;
        }
      }
    }

    // ---- online softmax: new running max per row, rescale what was accumulated ----
    float pr[R][KC];
    [[unroll]] for (int r = 0; r < R; ++r) {
      float mx = MASKED;
      [[unroll]] for (int kc = 0; kc < KC; ++kc) mx = valid[kc] ? max(mx, sc[r][kc]) : mx;
      float mnew = max(m[r], team_max(mx));
      float alpha = exp2(m[r] - mnew);
      m[r] = mnew;
      float sum = 0;
      [[unroll]] for (int kc = 0; kc < KC; ++kc) {
        pr[r][kc] = valid[kc] ? exp2(sc[r][kc] - mnew) : 0.0;
        sum += pr[r][kc];
      }
      l[r] = l[r] * alpha + sum;
      [[unroll]] for (int s = 0; s < DC; ++s) acc[r][s] *= alpha;
    }

    // ---- acc += p·v over the block's keys ----
#define PV_KEY_FROM_LANE(L)                                                       \
    {                                                                             \
      uint key = min(key0 + kc * TEAM + L, p.kv_len - 1);                         \
      uint vaddr = (kv_row0 + key) * p.v_stride + p.v_off + h * D4;               \
      vec4 vv[DC];                                                                \
      [[unroll]] for (int s = 0; s < DC; ++s) vv[s] = texelFetch(V, int(vaddr + min(s * TEAM + lane, D4 - 1))); \
      [[unroll]] for (int r = 0; r < R; ++r) {                                    \
        float pb = BCAST(pr[r][kc], L);                                           \
        [[unroll]] for (int s = 0; s < DC; ++s) acc[r][s] += pb * vv[s];         \
      }                                                                           \
    }
    [[unroll]] for (int kc = 0; kc < KC; ++kc) {
      PV_KEY_FROM_LANE(0)
      PV_KEY_FROM_LANE(1)
      PV_KEY_FROM_LANE(2)
      PV_KEY_FROM_LANE(3)
      PV_KEY_FROM_LANE(4)
      PV_KEY_FROM_LANE(5)
      PV_KEY_FROM_LANE(6)
      PV_KEY_FROM_LANE(7)
    }
  }

  // ---- normalise and store my columns of each row ----
  [[unroll]] for (int r = 0; r < R; ++r) {
    float inv = 1.0 / team_sum(l[r]);
    uint row = row0 + r;
    if (row < p.q_len) {
      uint base = (b * p.q_len + row) * p.o_stride + p.o_off + h * D4;
      [[unroll]] for (int s = 0; s < DC; ++s) {
        uint c = s * TEAM + lane;
        if (c < D4) o[base + c] = acc[r][s] * inv;
      }
    }
  }
}
