#version 450
// Sinusoidal timestep embedding (diffusers get_timestep_embedding): t [B] -> [B, D] with half = D/2,
// freq_k = exp(-ln(1e4) * k / (half - freq_shift)), arg = scale * (t * freq_k) in fp32, and
// [sin | cos] or, with flip, [cos | sin]; odd D gets a zero last column. exp, the division and sin/cos are
// written out here (Cody-Waite reduction + minimax polynomials, about 1 ulp) instead of the built-ins,
// whose Vulkan precision is loose (sin/cos are only bounded on [-pi, pi]) and differs between drivers:
// arguments reach ~1000 rad for t = 999.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize

layout(std430, binding = 0) readonly buffer T { float timesteps[]; };
layout(std430, binding = 1) writeonly buffer E { float emb[]; };

layout(push_constant) uniform Push { uint B, D, half_dim, flip; float freq_shift, scale; } p;

const float NEG_LN_1E4 = -9.21034049987793;  // float32(-log(10000))

float exp_accurate(float v) {
  // v = n*ln2 + r, with ln2 split so v - n*LN2_HI is exact; r and the sums 1 + r + r^2*poly(r) are carried
  // as (value, rounding error) pairs so the result is correctly rounded in all but ~1% of cases.
  precise float n = floor(v * 1.44269504088896341 + 0.5);
  precise float r_hi = v - n * 0.693359375;
  precise float r_lo = n * 2.12194440e-4;
  precise float r = r_hi + r_lo;
  precise float r_err = r_lo - (r - r_hi);
  float y = 1.9875691500e-4;
  y = y * r + 1.3981999507e-3;
  y = y * r + 8.3334519073e-3;
  y = y * r + 4.1665795894e-2;
  y = y * r + 1.6666665459e-1;
  y = y * r + 5.0000001201e-1;
  precise float p = y * (r * r);
  precise float s = r + p;
  precise float s_err = p - (s - r);
  precise float h = 1.0 + s;
  precise float h_err = s - (h - 1.0);
  precise float result = h + (h_err + s_err + r_err * h);
  return ldexp(result, int(n));
}

// Veltkamp split of a into hi + lo with 12-bit halves, so hi*hi, hi*lo, lo*lo are exact in fp32.
void split(float a, out float hi, out float lo) {
  precise float c = 4097.0 * a;
  precise float h = c - (c - a);
  hi = h;
  lo = a - h;
}

// num - a*b computed exactly when a*b is close to num (Dekker's two-product, no fma needed).
float residual_of_product(float num, float a, float b) {
  float ah, al, bh, bl;
  split(a, ah, al);
  split(b, bh, bl);
  precise float prod = a * b;
  precise float err = ((ah * bh - prod) + ah * bl + al * bh) + al * bl;  // a*b = prod + err exactly
  precise float res = (num - prod) - err;
  return res;
}

// sin and cos of a after reduction by pi/2 (pi/2 split in three so k*PIO2_1 and k*PIO2_2 are exact).
vec2 sincos_accurate(float a) {
  precise float k = floor(a * 0.636619772367581343 + 0.5);
  precise float r = a - k * 1.5703125;
  r = r - k * 4.837512969970703125e-4;
  r = r - k * 7.54978995489188216e-8;
  float z = r * r;
  float s = r + r * z * ((-1.9515295891e-4 * z + 8.3321608736e-3) * z - 1.6666654611e-1);
  float c = 1.0 - 0.5 * z + z * z * ((2.443315711809948e-5 * z - 1.388731625493765e-3) * z + 4.166664568298827e-2);
  uint q = uint(int(k) & 3);
  if (q == 0u) return vec2(s, c);
  if (q == 1u) return vec2(c, -s);
  if (q == 2u) return vec2(-s, -c);
  return vec2(-c, s);
}

void main() {
  uint id = flat_index();
  if (id >= p.B * p.half_dim) return;
  uint b = id / p.half_dim, k = id - b * p.half_dim;

  // exponent = (-ln(1e4) * k) / (half - shift), correctly rounded: q0 = num * (1/den), then one correction
  // with the exact residual num - q0*den. The product is split exactly (Dekker) instead of using fma(),
  // which some drivers (lavapipe) evaluate unfused.
  precise float num = NEG_LN_1E4 * float(k);
  float den = float(p.half_dim) - p.freq_shift;
  float inv = 1.0 / den;
  precise float q0 = num * inv;
  precise float expo = q0 + residual_of_product(num, q0, den) * inv;
  float freq = exp_accurate(expo);
  precise float arg = timesteps[b] * freq;
  arg = p.scale * arg;

  vec2 sc = sincos_accurate(arg);
  uint row = b * p.D;
  uint first = p.flip != 0u ? 1u : 0u;  // which of (sin, cos) goes to the first half
  emb[row + k] = first == 1u ? sc.y : sc.x;
  emb[row + p.half_dim + k] = first == 1u ? sc.x : sc.y;
  if (k == 0u && (p.D & 1u) != 0u) emb[row + p.D - 1] = 0.0;
}
