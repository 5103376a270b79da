// main() of attention_flash_coopmat.comp and its twin. Each includer defines, before including this:
//   SG_ID, SG_LANE     the subgroup (0..3) and lane (0..31) of the invocation
//   SG_BARRIER()       orders the shared-memory accesses of one subgroup (the twin: the workgroup's)
//   PAIR_XOR(x)        x of the lane whose index differs in bit 0
//   LOAD_Q()           takes the subgroup's Q (16 x D fp16, row-major at sP[sgP], stride D)
//   SCORES()           S = Q·Kᵀ (16 x BK, fp32) into sS[sgS], row-major, stride BK; K is sK [key][dim]
//   PV()               O_tile = P·V (16 x D, fp32) into sS[sgS], row-major, stride D; P is sP[sgP] [row][key]
void main() {
  const uint h = gl_WorkGroupID.y, b = gl_WorkGroupID.z, tid = gl_LocalInvocationID.x;
  const uint sg = SG_ID, lane = SG_LANE;
  const uint sgS = sg * ROWS * BK, sgP = sg * ROWS * BK;
  const uint row_base = gl_WorkGroupID.x * (SUBGROUPS * ROWS) + sg * ROWS;
  const uint kbase = b * p.k_bstride + h * p.k_hstride + p.k_off;
  const uint vbase = b * p.v_bstride + h * p.v_hstride + p.v_off;
  // Softmax and O ownership: lane pair (2r, 2r + 1) owns row r; `side` picks columns of S and of O.
  const uint r = lane >> 1, side = lane & 1;

  // ---- Q (16 rows of this subgroup) -> fp16 A fragments, pre-scaled into the exp2 domain ----
  const float qscale = p.scale * LOG2E;
  for (uint i = lane; i < ROWS * D4; i += 32) {
    const uint rr = i / D4, c = i % D4;
    const uint row = min(row_base + rr, p.q_len - 1);  // rows past the end: a copy of the last, never stored
    const vec4 x = qb[(b * p.q_len + row) * p.q_stride + p.q_off + h * D4 + c] * qscale;
    const uint at = sgP + rr * D + c * 4;
    sP[at] = float16_t(x.x);
    sP[at + 1] = float16_t(x.y);
    sP[at + 2] = float16_t(x.z);
    sP[at + 3] = float16_t(x.w);
  }
  SG_BARRIER();
  LOAD_Q();  // Q (16 x D, row-major at sgP, stride D) -> the kernel's operand storage
  SG_BARRIER();  // every lane has its fragments before sP is reused for P

  vec4 o[D / 8];  // row r, columns side·D/2 .. +D/2
  [[unroll]] for (int e = 0; e < D / 8; ++e) o[e] = vec4(0);
  float m = MASKED, l = 0;

  for (uint tile0 = 0; tile0 < p.kv_len; tile0 += BK) {
    // ---- stage K and V (fp16; keys past the end are zeros, so no NaN reaches the products) ----
    barrier();  // every subgroup is done with the previous tile
    for (uint i = tid; i < BK * D4; i += gl_WorkGroupSize.x) {
      const uint j = i / D4, c = i % D4, key = tile0 + j;
      vec4 kx = vec4(0), vx = vec4(0);
      if (key < p.kv_len) {
        kx = kb[kbase + key * p.k_stride + c];
        vx = vb[vbase + key * p.v_stride + c];
      }
      const uint at = j * D + c * 4;
      sK[at] = float16_t(kx.x);
      sK[at + 1] = float16_t(kx.y);
      sK[at + 2] = float16_t(kx.z);
      sK[at + 3] = float16_t(kx.w);
      sV[at] = float16_t(vx.x);
      sV[at + 1] = float16_t(vx.y);
      sV[at + 2] = float16_t(vx.z);
      sV[at + 3] = float16_t(vx.w);
    }
    barrier();

    // ---- S = Q·Kᵀ (16 x BK) into the subgroup's slice of sS, row-major, stride BK ----
    SCORES();
    SG_BARRIER();

    // ---- online softmax of row r over this tile (fp32); P to shared as fp16 ----
    const uint c0 = side * (BK / 2);
    float mx = m;
    for (uint c = 0; c < BK / 2; ++c)
      if (tile0 + c0 + c < p.kv_len) mx = max(mx, sS[sgS + r * BK + c0 + c]);
    mx = max(mx, PAIR_XOR(mx));
    const float alpha = exp2(m - mx);
    m = mx;
    float sum = 0;
    for (uint c = 0; c < BK / 2; ++c) {
      const float16_t pv =
          tile0 + c0 + c < p.kv_len ? float16_t(exp2(sS[sgS + r * BK + c0 + c] - mx)) : float16_t(0.0);
      sP[sgP + r * BK + c0 + c] = pv;
      sum += float(pv);
    }
    sum += PAIR_XOR(sum);
    l = l * alpha + sum;
    [[unroll]] for (int e = 0; e < D / 8; ++e) o[e] *= alpha;
    SG_BARRIER();

    // ---- O_tile = P·V (16 x D) into the scores' slice (row-major, stride D), then added to O by the lanes ----
    PV();
    SG_BARRIER();
    [[unroll]] for (int e = 0; e < D / 8; ++e) {
      const uint at = sgS + r * D + side * (D / 2) + e * 4;
      o[e] += vec4(sS[at], sS[at + 1], sS[at + 2], sS[at + 3]);
    }
    // The next tile's first barrier() orders these reads before the next scores overwrite the slice.
  }

  const uint row = row_base + r;
  if (row < p.q_len) {
    const float inv = 1.0 / l;
    const uint base = (b * p.q_len + row) * p.o_stride + p.o_off + h * D4 + side * (D / 8);
    [[unroll]] for (int e = 0; e < D / 8; ++e) ob[base + e] = o[e] * inv;
  }
}
