// Declarations shared by attention_flash_coopmat.comp (tensor cores) and attention_flash_coopmat_twin.comp (its
// fp32 twin, tested on lavapipe): spec constants, bindings, push constants, shared tiles. See the former.
layout(local_size_x = 128) in;

layout(constant_id = 0) const int D = 64;   // head_dim: a multiple of 16, at most BK
layout(constant_id = 1) const int BK = 64;  // keys per tile: a multiple of 16
const int D4 = D / 4, D16 = D / 16, BK16 = BK / 16;
const int ROWS = 16;  // query rows per subgroup
const int SUBGROUPS = 4;

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

shared float16_t sK[BK * D];                  // [key][dim]
shared float16_t sV[BK * D];                  // [key][dim]
shared float sS[SUBGROUPS * ROWS * BK];       // per subgroup: scores [16][BK], then the O tile [16][D]
shared float16_t sP[SUBGROUPS * ROWS * BK];   // per subgroup: Q staging [16][D], then P [16][BK]

