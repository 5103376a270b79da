// Body of the nn/eltwise_binary* shaders: z = op(x, y) with y broadcast as y[(e / inner) % C] for element e
// of x. That one rule covers same shape (inner 1, C = n), a scalar (C 1), a row vector [D] over [rows, D]
// (inner 1, C = D) and a per-channel vector [C] over [outer, C, inner]. z may alias x or y (in place).
// OP 0: z = alpha·x + beta·y (add, sub, axpby); 1: z = alpha·x·y (mul).
// Variants: (none) one element per step; VEC4: x, y, z as vec4 (y same shape or rows with C % 4 == 0);
// VEC4 + Y_SCALAR: x, z as vec4 and y gathered per component (any broadcast, n % 4 == 0).
layout(constant_id = 0) const uint OP = 0;
layout(local_size_x = 64) in;
#ifdef VEC4
#define T vec4
#else
#define T float
#endif
#if defined(VEC4) && !defined(Y_SCALAR)
#define TY vec4
#else
#define TY float
#endif
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) readonly buffer Y { TY y[]; };
layout(std430, binding = 2) writeonly buffer Z { T z[]; };
layout(push_constant) uniform Push {
  uint n;      // in units of T
  uint C;      // broadcast period of y, in elements
  uint inner;  // elements of x per y element
  float alpha, beta;
  uint span;   // items per workgroup (a multiple of 64)
} p;

T load_y(uint i) {
#if !defined(VEC4)
  if (p.C == p.n) return y[i];  // same shape: no division
  return y[(i / p.inner) % p.C];
#elif !defined(Y_SCALAR)
  if (p.C == p.n * 4u) return y[i];  // same shape: no division
  return y[(i * 4u) % p.C / 4u];     // rows: C % 4 == 0, inner == 1
#else
  uint e = i * 4u;
  if (p.inner % 4u == 0u) return vec4(y[(e / p.inner) % p.C]);  // one y value per vec4
  return vec4(y[(e / p.inner) % p.C], y[((e + 1u) / p.inner) % p.C], y[((e + 2u) / p.inner) % p.C],
              y[((e + 3u) / p.inner) % p.C]);
#endif
}

void main() {
  // Each workgroup streams one contiguous span, lanes interleaved inside it: coalesced on GPUs and
  // sequential per workgroup on CPU drivers (a grid-stride loop would jump by MiBs every iteration there).
  uint begin = gl_WorkGroupID.x * p.span, end = min(begin + p.span, p.n);
  for (uint i = begin + gl_LocalInvocationID.x; i < end; i += gl_WorkGroupSize.x) {
    T a = x[i], b = load_y(i);
    z[i] = OP == 0u ? p.alpha * a + p.beta * b : p.alpha * a * b;
  }
}
