// Broadcast indexing shared by the eltwise_binary* and eltwise_affine* shaders. The second operand (y, or
// s and t) is read at element (e / inner) % C for element e of x. Integer division by a run-time value is
// scalarised and slow on CPU drivers, so it happens once per invocation: the loop carries c = (e / inner) % C
// and r = e % inner and advances them by the grid stride with adds and compares (host-computed steps).
// MODE (specialization constant 1), chosen on the host; per vec4 of x at element e = 4i:
//   0 SAME      y has x's shape: element e itself
//   1 ROWS4     inner 1, C % 4 == 0: one aligned vec4 of y at c
//   2 ONE       inner % 4 == 0 (and scalars, normalised to inner = n): one value y[c]
//   3 SPLIT     inner ≥ 4 otherwise: y[c] or, past the end of the inner run, the next channel
//   4 ROWS_ODD  inner 1, C ≥ 4, C % 4 != 0: y[c], y[c+1], y[c+2], y[c+3] wrapping at C
//   5 GENERAL   anything else (inner 2 or 3, or C < 4 rows): divisions per component
// Non-vec4 shaders use 0 (element i) or 5.
// `base` shifts x's elements within y's period: a chunk of a split op starts at x element `base` of it.
// Needs push constant fields C, inner, step_c, step_r, base in block `p`.
layout(constant_id = 1) const uint MODE = 5;

struct Bcast {
  uint c, r;
};

Bcast bcast_start(uint e) {
  e += p.base;
  return Bcast((e / p.inner) % p.C, e % p.inner);
}

void bcast_step(inout Bcast b) {
  b.r += p.step_r;
  if (b.r >= p.inner) {
    b.r -= p.inner;
    b.c += 1u;
  }
  b.c += p.step_c;
  if (b.c >= p.C) b.c -= p.C;
}

// Element indices of the second operand for the four x elements at e (MODE 2..5).
uvec4 bcast_index4(Bcast b, uint e) {
  if (MODE == 2u) return uvec4(b.c);
  if (MODE == 3u) {
    uint next = b.c + 1u == p.C ? 0u : b.c + 1u;
    return uvec4(b.c, b.r + 1u < p.inner ? b.c : next, b.r + 2u < p.inner ? b.c : next,
                 b.r + 3u < p.inner ? b.c : next);
  }
  if (MODE == 4u) {
    uvec4 k = uvec4(b.c) + uvec4(0u, 1u, 2u, 3u);
    return mix(k, k - uvec4(p.C), greaterThanEqual(k, uvec4(p.C)));
  }
  return ((uvec4(e + p.base) + uvec4(0u, 1u, 2u, 3u)) / p.inner) % p.C;
}
