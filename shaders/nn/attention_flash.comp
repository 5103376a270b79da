#version 450
#extension GL_EXT_control_flow_attributes : require
// Flash attention for GPUs without tensor cores (DeviceTuning::attention = tiled): out = softmax(q·kᵀ·scale)·v
// per (batch, head), online softmax in fp32 in the exp2 domain (as attention.comp).
//
// Work split: a workgroup takes BQ query rows of one (batch, head), one row per invocation (its q row, running
// max/sum and output accumulators live in registers). The keys are walked in tiles of BK: all invocations
// stage the tile's K and V rows (fp32) in shared memory, then every invocation reads them at the same address
// (a shared-memory broadcast) for its own row. ops_attention.cpp picks BK so that the two tiles fit
// maxComputeSharedMemorySize (2·BK·D·4 bytes: 64 keys at D = 64 are 32 KiB).
//
// Storage buffers only (no texel views). No bias, key mask nor split-key running state: ops_attention.cpp
// runs such calls on attention.comp.
layout(local_size_x_id = 0) in;                 // BQ: query rows per workgroup
layout(constant_id = 1) const int D4 = 16;      // head_dim / 4
layout(constant_id = 2) const int BK = 64;      // keys per shared tile, a multiple of KB
layout(constant_id = 3) const bool O_F16 = false;  // out in fp16 (the next GEMM's X): o_off, o_stride in 4 halves
layout(constant_id = 4) const bool KV_F16 = false;  // k and v in fp16: their offsets and strides in 4 halves
layout(constant_id = 5) const bool Q_F16 = false;   // q in fp16: its offset and strides in 4 halves
const int KB = 4;                               // keys per step of the online softmax

const float LOG2E = 1.4426950408889634;
const float MASKED = -3.4028234663852886e38;  // -FLT_MAX: the running max before any key

layout(std430, binding = 0) readonly buffer Qb { vec4 qb[]; };
layout(std430, binding = 0) readonly buffer Qh { uvec2 qh[]; };  // Q_F16: 4 halves per element
vec4 q4(uint i) { return Q_F16 ? vec4(unpackHalf2x16(qh[i].x), unpackHalf2x16(qh[i].y)) : qb[i]; }
layout(std430, binding = 1) readonly buffer Kb { vec4 kb[]; };
layout(std430, binding = 2) readonly buffer Vb { vec4 vb[]; };
layout(std430, binding = 1) readonly buffer Kh { uvec2 kh[]; };  // KV_F16: 4 halves per element
layout(std430, binding = 2) readonly buffer Vh { uvec2 vh[]; };
vec4 k4(uint i) { return KV_F16 ? vec4(unpackHalf2x16(kh[i].x), unpackHalf2x16(kh[i].y)) : kb[i]; }
vec4 v4(uint i) { return KV_F16 ? vec4(unpackHalf2x16(vh[i].x), unpackHalf2x16(vh[i].y)) : vb[i]; }
layout(std430, binding = 3) writeonly buffer Ob { vec4 ob[]; };
layout(std430, binding = 3) writeonly buffer Oh { uvec2 oh[]; };  // O_F16: 4 halves per element

// The same layout as attention.comp's push constants (vec4 units); the bias and mask fields are unused here, and
// q's batch and head strides are the flash kernels' own (q token-major or head-major).
layout(push_constant) uniform Push {
  uint q_len, kv_len, heads;
  uint q_off, q_stride, o_off, o_stride;
  uint k_off, k_stride, k_bstride, k_hstride;
  uint v_off, v_stride, v_bstride, v_hstride;
  float scale;
  uint bias_off, bias_hstride, bias_rstride, mask_off;
  uint q_bstride, q_hstride;
} p;

shared vec4 ks[BK * D4];
shared vec4 vs[BK * D4];

void main() {
  const uint h = gl_WorkGroupID.y, b = gl_WorkGroupID.z, tid = gl_LocalInvocationID.x;
  const uint nthreads = gl_WorkGroupSize.x;
  const uint row = gl_WorkGroupID.x * nthreads + tid;
  const uint kbase = b * p.k_bstride + h * p.k_hstride + p.k_off;
  const uint vbase = b * p.v_bstride + h * p.v_hstride + p.v_off;

  // My q row, pre-multiplied by scale·log2(e): scores in the exp2 domain. Rows past the end compute a copy
  // of the last row (they must still help stage the tiles) and store nothing.
  vec4 q[D4], acc[D4];
  {
    const uint base = b * p.q_bstride + h * p.q_hstride + min(row, p.q_len - 1) * p.q_stride + p.q_off;
    [[unroll]] for (int c = 0; c < D4; ++c) {
      q[c] = q4(base + c) * (p.scale * LOG2E);
      acc[c] = vec4(0);
    }
  }
  float m = MASKED, l = 0;

  for (uint tile0 = 0; tile0 < p.kv_len; tile0 += BK) {
    const uint tile_keys = min(uint(BK), p.kv_len - tile0);
    barrier();  // everyone is done with the previous tile
    for (uint i = tid; i < tile_keys * D4; i += nthreads) {
      const uint j = i / D4, c = i % D4;
      ks[i] = k4(kbase + (tile0 + j) * p.k_stride + c);
      vs[i] = v4(vbase + (tile0 + j) * p.v_stride + c);
    }
    barrier();

    for (uint j0 = 0; j0 < tile_keys; j0 += KB) {
      float s[KB];
      [[unroll]] for (int j = 0; j < KB; ++j) {
        // Keys past the tile's end read a valid (staged) key and are dropped below.
        const uint key = min(j0 + j, tile_keys - 1) * D4;
        float x = 0;
        [[unroll]] for (int c = 0; c < D4; ++c) x += dot(q[c], ks[key + c]);
        s[j] = x;
      }
      float mx = m;
      [[unroll]] for (int j = 0; j < KB; ++j) mx = j0 + j < tile_keys ? max(mx, s[j]) : mx;
      const float alpha = exp2(m - mx);
      m = mx;
      float sum = 0;
      [[unroll]] for (int j = 0; j < KB; ++j) {
        s[j] = j0 + j < tile_keys ? exp2(s[j] - mx) : 0.0;
        sum += s[j];
      }
      l = l * alpha + sum;
      [[unroll]] for (int c = 0; c < D4; ++c) acc[c] *= alpha;
      [[unroll]] for (int j = 0; j < KB; ++j) {
        const uint key = min(j0 + j, tile_keys - 1) * D4;
        [[unroll]] for (int c = 0; c < D4; ++c) acc[c] = fma(vec4(s[j]), vs[key + c], acc[c]);
      }
    }
  }

  if (row < p.q_len) {
    const float inv = 1.0 / l;
    const uint base = (b * p.q_len + row) * p.o_stride + p.o_off + h * D4;
    [[unroll]] for (int c = 0; c < D4; ++c) {
      const vec4 o = acc[c] * inv;
      if (O_F16) {
        oh[base + c] = uvec2(packHalf2x16(o.xy), packHalf2x16(o.zw));
      } else {
        ob[base + c] = o;
      }
    }
  }
}
