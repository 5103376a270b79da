// Declarations shared by attention_flash_coopmat.comp (tensor cores), attention_flash_coopmat_twin.comp (its
// fp32 twin, tested on lavapipe) and attention_flash_coopmat2.comp (its VK_NV_cooperative_matrix2 variant): spec
// constants, bindings, push constants, the K and V tiles. See the first.
// The layout comes from the tuning table (DeviceTuning::attention_coopmat_subgroups, attention_block_k,
// coopmat, coopmat_lanes; tensor/coopmat_layout.cpp checks it against the device and the head_dim).
layout(local_size_x_id = 7) in;  // SUBGROUPS * LANES

layout(constant_id = 0) const int D = 64;          // head_dim: a multiple of FRAG_K, FRAG_N and 4·LPR, at most BK
layout(constant_id = 1) const int BK = 64;         // keys per tile: a multiple of FRAG_N, FRAG_K and LPR
layout(constant_id = 2) const int SUBGROUPS = 4;   // per workgroup, ROWS query rows each
layout(constant_id = 3) const int ROWS = 16;       // the fragment shape: ROWS x FRAG_N x FRAG_K
layout(constant_id = 4) const int FRAG_N = 16;
layout(constant_id = 5) const int FRAG_K = 16;
layout(constant_id = 6) const int LANES = 32;      // the subgroup size (required at pipeline creation; the twin emulates it)
layout(constant_id = 8) const bool O_F16 = false;  // out in fp16 (the next GEMM's X): o_off, o_stride in 4 halves
layout(constant_id = 9) const bool KV_F16 = false;  // k and v in fp16 (the operand type): offsets, strides in 4 halves
layout(constant_id = 10) const bool Q_F16 = false;  // q in fp16: its offset and strides in 4 halves
const int D4 = D / 4;
// Softmax and O ownership: LPR lanes per row where a subgroup has more lanes than rows (the H200: 32 lanes,
// 16 rows, 2 lanes a row), else RPL rows per lane (lavapipe at 16 rows: 8 lanes, 2 rows a lane); each lane of a
// row takes BK / LPR of its keys and D / LPR of its O columns.
const int LPR = (LANES + ROWS - 1) / ROWS;
const int RPL = (ROWS + LANES - 1) / LANES;
const int PASS = LANES / LPR;   // rows the subgroup's lanes own at once
const int COLS = BK / LPR;      // keys of a row per lane
const int OV = D / (4 * LPR);   // vec4 of O per row per lane
// Row pitches of the shared tiles, padded by 16 bytes: a multiple of 16 bytes (coopMatLoad/Store's stride
// alignment) that is not one of 128 bytes, so the rows of a fragment, and the rows the softmax's lanes walk at
// once, start on different banks instead of all on the same one (unpadded, every access was an 8- to 32-way
// bank conflict on NVIDIA's 32 four-byte banks).
const int KP = D + 8;   // sK, sV: halves per key row
const int PP = BK + 8;  // sP: halves per row, of Q (D <= BK) and of P
const int SP = BK + 4;  // sS: floats per row, of the scores and of the O tile (D <= BK)

const float LOG2E = 1.4426950408889634;
const float MASKED = -3.4028234663852886e38;  // -FLT_MAX: the running max before any key

layout(std430, binding = 0) readonly buffer Qb { vec4 qb[]; };
layout(std430, binding = 0) readonly buffer Qh { uvec2 qh[]; };  // Q_F16: 4 halves per element
layout(std430, binding = 1) readonly buffer Kb { vec4 kb[]; };
layout(std430, binding = 2) readonly buffer Vb { vec4 vb[]; };
layout(std430, binding = 1) readonly buffer Kh { uvec2 kh[]; };  // KV_F16: 4 halves per element
layout(std430, binding = 2) readonly buffer Vh { uvec2 vh[]; };
layout(std430, binding = 3) writeonly buffer Ob { vec4 ob[]; };
layout(std430, binding = 3) writeonly buffer Oh { uvec2 oh[]; };  // O_F16: 4 halves per element

// Stores one vec4 of O at element-group i of the out binding (vec4 units, or 4-half units under O_F16).
void store_o(uint i, vec4 o) {
  if (O_F16) {
    oh[i] = uvec2(packHalf2x16(o.xy), packHalf2x16(o.zw));
  } else {
    ob[i] = o;
  }
}

// attention.comp's push constants (vec4 units) and q's batch and head strides; the bias and mask fields are unused here.
layout(push_constant) uniform Push {
  uint q_len, kv_len, heads;
  uint q_off, q_stride, o_off, o_stride;
  uint k_off, k_stride, k_bstride, k_hstride;
  uint v_off, v_stride, v_bstride, v_hstride;
  float scale;
  uint bias_off, bias_hstride, bias_rstride, mask_off;
  uint q_bstride, q_hstride;  // the flash kernels' own: q token-major or head-major
} p;

// Vec4 c of row `row` of q's head h in batch element b (converted from fp16 under Q_F16).
vec4 load_q(uint b, uint h, uint row, uint c) {
  const uint i = b * p.q_bstride + h * p.q_hstride + row * p.q_stride + p.q_off + c;
  return Q_F16 ? vec4(unpackHalf2x16(qh[i].x), unpackHalf2x16(qh[i].y)) : qb[i];
}

shared float16_t sK[BK * KP];                 // [key][dim], pitch KP
shared float16_t sV[BK * KP];                 // [key][dim], pitch KP

// The K and V tile is prefetched: load_kv reads the next tile into registers while the current one is in use,
// store_kv writes them (fp16) to sK/sV once every subgroup is done with it. Invocation i takes the vec4s
// i + WG·r of the tile (key (i + WG·r) / D4, column (i + WG·r) % D4); keys past the end are zeros, so no NaN
// reaches the products.
const uint KV_PER = (BK * D4 + gl_WorkGroupSize.x - 1) / gl_WorkGroupSize.x;
vec4 rk[KV_PER], rv[KV_PER];

void load_kv(uint tile0, uint kbase, uint vbase) {
  [[unroll]] for (uint r = 0; r < KV_PER; ++r) {
    const uint i = gl_LocalInvocationID.x + gl_WorkGroupSize.x * r, key = tile0 + i / D4, c = i % D4;
    rk[r] = vec4(0);
    rv[r] = vec4(0);
    if (i < BK * D4 && key < p.kv_len) {
      if (KV_F16) {  // already the operand values: the fp16 stores below keep them
        const uvec2 hk = kh[kbase + key * p.k_stride + c], hv = vh[vbase + key * p.v_stride + c];
        rk[r] = vec4(unpackHalf2x16(hk.x), unpackHalf2x16(hk.y));
        rv[r] = vec4(unpackHalf2x16(hv.x), unpackHalf2x16(hv.y));
      } else {
        rk[r] = kb[kbase + key * p.k_stride + c];
        rv[r] = vb[vbase + key * p.v_stride + c];
      }
    }
  }
}

void store_kv() {
  [[unroll]] for (uint r = 0; r < KV_PER; ++r) {
    const uint i = gl_LocalInvocationID.x + gl_WorkGroupSize.x * r;
    if (i < BK * D4) {
      const uint at = (i / D4) * KP + (i % D4) * 4;
      sK[at] = float16_t(rk[r].x);
      sK[at + 1] = float16_t(rk[r].y);
      sK[at + 2] = float16_t(rk[r].z);
      sK[at + 3] = float16_t(rk[r].w);
      sV[at] = float16_t(rv[r].x);
      sV[at + 1] = float16_t(rv[r].y);
      sV[at + 2] = float16_t(rv[r].z);
      sV[at + 3] = float16_t(rv[r].w);
    }
  }
}
