// Body of nn/eltwise_unary (float elements) and nn/eltwise_unary_vec4 (VEC4: 4 elements per load/store,
// for element counts that are multiples of 4). y = f(x); x and y may be the same buffer (in place).
// OP 0: a·x + b (scale/shift); 1: SiLU; 2: GELU, tanh approximation (PyTorch approximate='tanh');
//    3: clamp(x, a, b).
layout(constant_id = 0) const uint OP = 0;
layout(local_size_x = 64) in;
#ifdef VEC4
#define T vec4
#else
#define T float
#endif
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) writeonly buffer Y { T y[]; };
layout(push_constant) uniform Push {
  uint n;  // in units of T
  float a, b;
  uint span;  // items per workgroup (a multiple of 64)
} p;

// tanh from one exp of a non-positive argument: never overflows (inf/inf) for large |u|.
T tanh_safe(T u) {
  T t = exp(-2.0 * abs(u));
  return sign(u) * (1.0 - t) / (1.0 + t);
}

T apply(T v) {
  if (OP == 0u) return p.a * v + p.b;
  if (OP == 1u) return v / (1.0 + exp(-v));
  if (OP == 2u) return 0.5 * v * (1.0 + tanh_safe(0.7978845608028654 * (v + 0.044715 * v * v * v)));
  return clamp(v, p.a, p.b);
}

void main() {
  // One contiguous span per workgroup, lanes interleaved (see eltwise_binary.glsl).
  uint begin = gl_WorkGroupID.x * p.span, end = min(begin + p.span, p.n);
  for (uint i = begin + gl_LocalInvocationID.x; i < end; i += gl_WorkGroupSize.x) y[i] = apply(x[i]);
}
