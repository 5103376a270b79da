// Body of the nn/eltwise_binary* shaders: z = op(x, y) with y broadcast as y[(e / inner) % C] for element e
// of x. That one rule covers same shape (inner 1, C = n), a scalar (C 1), a row vector [D] over [rows, D]
// (inner 1, C = D) and a per-channel vector [C] over [outer, C, inner]. z may alias x or y (in place).
// OP 0: z = alpha·x + beta·y (add, sub, axpby); 1: z = alpha·x·y (mul).
// Variants: (none) one element per step; VEC4: x, y, z as vec4 (y same shape or rows with C % 4 == 0);
// VEC4 + Y_SCALAR: x, z as vec4 and y gathered per component (any broadcast, n % 4 == 0);
// TEXEL: x (RGBA32F) and y read through texel buffers (~2-3x faster loads on lavapipe), z as vec4; y is bound
// as RGBA32F when y_vec4 (same shape or rows with C % 4 == 0) and as R32F otherwise.
layout(constant_id = 0) const uint OP = 0;
layout(local_size_x = 64) in;
#if defined(VEC4) || defined(TEXEL)
#define T vec4
#else
#define T float
#endif
#if defined(VEC4) && !defined(Y_SCALAR)
#define TY vec4
#else
#define TY float
#endif
#ifdef TEXEL
layout(binding = 0) uniform samplerBuffer x_tex;
layout(binding = 1) uniform samplerBuffer y_tex;
#define LOAD_X(i) texelFetch(x_tex, int(i))
#define Y1(j) texelFetch(y_tex, int(j)).x
#else
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) readonly buffer Y { TY y[]; };
#define LOAD_X(i) x[i]
#define Y1(j) y[j]
#endif
layout(std430, binding = 2) writeonly buffer Z { T z[]; };
layout(push_constant) uniform Push {
  uint n;      // in units of T
  uint C;      // broadcast period of y, in elements
  uint inner;  // elements of x per y element
  float alpha, beta;
  uint y_vec4; // TEXEL: y bound as RGBA32F
} p;

#if defined(TEXEL) || defined(Y_SCALAR)
// Four y values for the vec4 of x at element e = 4i, read one by one.
vec4 gather_y(uint i) {
  uint e = i * 4u;
  if (p.inner % 4u == 0u) return vec4(Y1((e / p.inner) % p.C));  // one y value per vec4
  return vec4(Y1((e / p.inner) % p.C), Y1(((e + 1u) / p.inner) % p.C), Y1(((e + 2u) / p.inner) % p.C),
              Y1(((e + 3u) / p.inner) % p.C));
}
#endif

T load_y(uint i) {
#if defined(TEXEL)
  if (p.y_vec4 != 0u) return texelFetch(y_tex, int(p.C == p.n * 4u ? i : (i * 4u) % p.C / 4u));
  return gather_y(i);
#elif !defined(VEC4)
  if (p.C == p.n) return y[i];  // same shape: no division
  return y[(i / p.inner) % p.C];
#elif !defined(Y_SCALAR)
  if (p.C == p.n * 4u) return y[i];  // same shape: no division
  return y[(i * 4u) % p.C / 4u];     // rows: C % 4 == 0, inner == 1
#else
  return gather_y(i);
#endif
}

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint i = gl_GlobalInvocationID.x; i < p.n; i += stride) {
    T a = LOAD_X(i), b = load_y(i);
    z[i] = OP == 0u ? p.alpha * a + p.beta * b : p.alpha * a * b;
  }
}
