// The linear kernels' output side, shared by every family (linear.comp: texel inputs; linear_storage_io.glsl:
// storage inputs for the tiled and tensor-core kernels): the output and epilogue bindings (2-7), the push block and
// the 5 epilogue steps, so every family applies the same epilogue (ops_linear.hpp) from the same push constants.
#include "../common/erf.glsl"

layout(std430, binding = 2) writeonly buffer Yb { float y[]; };
layout(std430, binding = 3) readonly buffer Bias { uint bias[]; };  // f32, or 16-bit pairs
layout(std430, binding = 4) readonly buffer Scale { float scale[]; };
layout(std430, binding = 5) readonly buffer Shift { float shift[]; };
layout(std430, binding = 6) readonly buffer Gate { float gate[]; };
layout(std430, binding = 7) readonly buffer Res { float res[]; };

layout(push_constant) uniform Push {
  uint M, N, K, ldx, ldy, ldw;  // ldw: W row stride (the whole K; K is a chunk of it when K is split)
  uint x_off, w_off, y_off;      // element offsets in the bound views
  uint x_bs, w_bs, y_bs;         // batch strides in elements (w_bs 0: shared weight)
  uint bias_off, scale_off, shift_off, gate_off, res_off;
  uint vec_bs;                   // batch stride of scale, shift and gate (0: shared)
  uint flags;                    // bits 0-1 activation (1 GELU-tanh, 2 SiLU, 3 GELU-erf), 2 bias, 3 modulation, 4 gate,
                                 // 5 residual, 6-7 bias dtype (0 f32, 1 f16, 2 bf16)
} p;

float load_bias(uint n) {
  uint dt = (p.flags >> 6) & 3u, i = p.bias_off + n;
  if (dt == 0u) return uintBitsToFloat(bias[i]);
  uint u = bias[i >> 1], half_bits = (i & 1u) == 0u ? (u & 0xffffu) : (u >> 16);
  return dt == 1u ? unpackHalf2x16(half_bits).x : uintBitsToFloat(half_bits << 16);
}

float activate(float f, uint act) {
  if (act == 1u) {  // GELU, tanh approximation; tanh(u) = 1 - 2/(e^{2u}+1) stays finite for large |u|
    float u = 0.7978845608028654 * (f + 0.044715 * f * f * f);
    return 0.5 * f * (2.0 - 2.0 / (exp(2.0 * u) + 1.0));
  }
  if (act == 2u) return f / (1.0 + exp(-f));
  if (act == 3u) return gelu_erf(f);
  return f;
}

// The 5 epilogue steps on the product f of output (b, m, n); callers check m < M, n < N.
float epilogue_value(uint b, uint m, uint n, float f) {
  const uint flags = p.flags;
  if ((flags & 4u) != 0u) f += load_bias(n);
  f = activate(f, flags & 3u);
  uint v = b * p.vec_bs + n;
  if ((flags & 8u) != 0u) f = f * (1.0 + scale[p.scale_off + v]) + shift[p.shift_off + v];
  if ((flags & 16u) != 0u) f *= gate[p.gate_off + v];
  if ((flags & 32u) != 0u) f += res[p.res_off + b * p.y_bs + m * p.ldy + n];
  return f;
}

// The epilogue and the f32 store. The residual may alias Y: this invocation reads the element before writing it.
void store_output(uint b, uint m, uint n, float f) { y[p.y_off + b * p.y_bs + m * p.ldy + n] = epilogue_value(b, m, n, f); }
