// main() of attention_flash_coopmat.comp and its twin. Each includer defines, before including this:
//   SG_ID, SG_LANE     the subgroup (0..SUBGROUPS-1) and lane (0..LANES-1) of the invocation
//   SG_BARRIER()       orders the shared-memory accesses of one subgroup (the twin: the workgroup's)
//   LANE_XOR(x, mask)  x of the lane whose index differs by `mask` (a power of two below LPR)
//   LOAD_Q()           takes the subgroup's Q (ROWS x D fp16, row-major at sP[sgP], stride PP)
//   SCORES()           S = Q·Kᵀ·qscale (ROWS x BK, fp32) into sS[sgS], row-major, stride SP; K is sK [key][dim],
//                      stride KP
//   PV()               O_tile = P·V (ROWS x D, fp32) into sS[sgS], row-major, stride SP; P is sP[sgP] [row][key],
//                      stride PP; V is sV [key][dim], stride KP
shared float sS[SUBGROUPS * ROWS * SP];      // per subgroup: scores [ROWS][BK], then the O tile [ROWS][D], pitch SP
shared float16_t sP[SUBGROUPS * ROWS * PP];  // per subgroup: Q staging [ROWS][D], then P [ROWS][BK], pitch PP

void main() {
  const uint h = gl_WorkGroupID.y, b = gl_WorkGroupID.z;
  const uint sg = SG_ID, lane = SG_LANE;
  const uint sgS = sg * ROWS * SP, sgP = sg * ROWS * PP;
  const uint row_base = gl_WorkGroupID.x * (SUBGROUPS * ROWS) + sg * ROWS;
  const uint kbase = b * p.k_bstride + h * p.k_hstride + p.k_off;
  const uint vbase = b * p.v_bstride + h * p.v_hstride + p.v_off;
  // Softmax and O ownership: lane `part` of a row's LPR lanes takes its keys part + LPR·c (interleaved, so the
  // lanes of a row read neighbouring words) and its O columns part·D/LPR ..; this lane's rows are rw + PASS·q.
  const uint rw = lane / LPR, part = lane % LPR;

  // ---- Q (ROWS rows of this subgroup) -> fp16 A fragments, as given: the scores are scaled into the exp2 domain ----
  const float qscale = p.scale * LOG2E;  // SCORES() multiplies by it (fp32)
  for (uint i = lane; i < ROWS * D4; i += LANES) {
    const uint rr = i / D4, c = i % D4;
    const uint row = min(row_base + rr, p.q_len - 1);  // rows past the end: a copy of the last, never stored
    const vec4 x = load_q(b, h, row, c);
    const uint at = sgP + rr * PP + c * 4;
    sP[at] = float16_t(x.x);
    sP[at + 1] = float16_t(x.y);
    sP[at + 2] = float16_t(x.z);
    sP[at + 3] = float16_t(x.w);
  }
  SG_BARRIER();
  LOAD_Q();  // Q (ROWS x D, row-major at sgP, stride D) -> the kernel's operand storage
  SG_BARRIER();  // every lane has its fragments before sP is reused for P

  vec4 o[RPL][OV];  // rows rw + PASS·q, columns part·D/LPR .. +D/LPR
  float m[RPL], l[RPL];
  [[unroll]] for (int q = 0; q < RPL; ++q) {
    [[unroll]] for (int e = 0; e < OV; ++e) o[q][e] = vec4(0);
    m[q] = MASKED;
    l[q] = 0;
  }

  load_kv(0, kbase, vbase);
  for (uint tile0 = 0; tile0 < p.kv_len; tile0 += BK) {
    // ---- stage K and V; the next tile's loads then run during this tile's math ----
    barrier();  // every subgroup is done with the previous tile
    store_kv();
    barrier();
    if (tile0 + BK < p.kv_len) load_kv(tile0 + BK, kbase, vbase);

    // ---- S = Q·Kᵀ (ROWS x BK) into the subgroup's slice of sS, row-major, stride SP ----
    SCORES();
    SG_BARRIER();

    // ---- online softmax of this lane's rows over this tile (fp32); P to shared as fp16 ----
    [[unroll]] for (int q = 0; q < RPL; ++q) {
      const uint r = rw + PASS * q;
      float mx = m[q];
      for (uint c = 0; c < COLS; ++c) {
        const uint col = part + LPR * c;
        if (tile0 + col < p.kv_len) mx = max(mx, sS[sgS + r * SP + col]);
      }
      [[unroll]] for (int x = 1; x < LPR; x <<= 1) mx = max(mx, LANE_XOR(mx, x));
      const float alpha = exp2(m[q] - mx);
      m[q] = mx;
      float sum = 0;
      for (uint c = 0; c < COLS; ++c) {
        const uint col = part + LPR * c;
        const float16_t pv = tile0 + col < p.kv_len ? float16_t(exp2(sS[sgS + r * SP + col] - mx)) : float16_t(0.0);
        sP[sgP + r * PP + col] = pv;
        sum += float(pv);
      }
      [[unroll]] for (int x = 1; x < LPR; x <<= 1) sum += LANE_XOR(sum, x);
      l[q] = l[q] * alpha + sum;
      [[unroll]] for (int e = 0; e < OV; ++e) o[q][e] *= alpha;
    }
    SG_BARRIER();

    // ---- O_tile = P·V (ROWS x D) into the scores' slice (row-major, stride SP), then added to O by the lanes ----
    PV();
    SG_BARRIER();
    [[unroll]] for (int q = 0; q < RPL; ++q)
      [[unroll]] for (int e = 0; e < OV; ++e) {
        const uint at = sgS + (rw + PASS * q) * SP + part * (D / LPR) + e * 4;
        o[q][e] += vec4(sS[at], sS[at + 1], sS[at + 2], sS[at + 3]);
      }
    // The next tile's first barrier() orders these reads before the next scores overwrite the slice.
  }

  [[unroll]] for (int q = 0; q < RPL; ++q) {
    const uint row = row_base + rw + PASS * q;
    if (row < p.q_len) {
      const float inv = 1.0 / l[q];
      const uint base = (b * p.q_len + row) * p.o_stride + p.o_off + h * D4 + part * OV;
      [[unroll]] for (int e = 0; e < OV; ++e) store_o(base + e, o[q][e] * inv);
    }
  }
}
