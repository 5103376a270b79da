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
layout(std430, binding = 1) readonly buffer Kb { vec4 kb[]; };
layout(std430, binding = 2) readonly buffer Vb { vec4 vb[]; };
layout(std430, binding = 3) writeonly buffer Ob { vec4 ob[]; };

// attention.comp's push constants (vec4 units); the bias and mask fields are unused here.
layout(push_constant) uniform Push {
  uint q_len, kv_len, heads;
  uint q_off, q_stride, o_off, o_stride;
  uint k_off, k_stride, k_bstride, k_hstride;
  uint v_off, v_stride, v_bstride, v_hstride;
  float scale;
  uint bias_off, bias_hstride, bias_rstride, mask_off;
} p;

shared float16_t sK[BK * KP];                 // [key][dim], pitch KP
shared float16_t sV[BK * KP];                 // [key][dim], pitch KP

// Stages the workgroup's K and V tile from key tile0 (fp16; keys past the end are zeros, so no NaN reaches the
// products).
void stage_kv(uint tile0, uint kbase, uint vbase) {
  for (uint i = gl_LocalInvocationID.x; i < BK * D4; i += gl_WorkGroupSize.x) {
    const uint j = i / D4, c = i % D4, key = tile0 + j;
    vec4 kx = vec4(0), vx = vec4(0);
    if (key < p.kv_len) {
      kx = kb[kbase + key * p.k_stride + c];
      vx = vb[vbase + key * p.v_stride + c];
    }
    const uint at = j * KP + c * 4;
    sK[at] = float16_t(kx.x);
    sK[at + 1] = float16_t(kx.y);
    sK[at + 2] = float16_t(kx.z);
    sK[at + 3] = float16_t(kx.w);
    sV[at] = float16_t(vx.x);
    sV[at + 1] = float16_t(vx.y);
    sV[at + 2] = float16_t(vx.z);
    sV[at + 3] = float16_t(vx.w);
  }
}
