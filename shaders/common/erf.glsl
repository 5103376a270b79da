// erf(x) in fp32 for the exact (erf) GELU of PyTorch's nn.GELU() (DINOv2, Video-Depth-Anything). GLSL has no
// erf: this is the Chebyshev-fitted erfc of Numerical Recipes (erfcc, fractional error < 1.2e-7 everywhere),
// erf = 1 - erfc on x >= 0 and odd symmetry below. Absolute error of erf ~1e-7, far inside every golden
// tolerance; GELU = 0.5·x·(1 + erf(x/√2)) inherits it scaled by |x|/2.
float erf_f32(float x) {
  float z = abs(x), t = 1.0 / (1.0 + 0.5 * z);
  float poly = -1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (-0.18628806 +
               t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277))))))));
  float erfc_z = t * exp(-z * z + poly);
  return x >= 0.0 ? 1.0 - erfc_z : erfc_z - 1.0;
}

float gelu_erf(float x) { return 0.5 * x * (1.0 + erf_f32(x * 0.70710678118654752)); }
vec4 gelu_erf(vec4 v) { return vec4(gelu_erf(v.x), gelu_erf(v.y), gelu_erf(v.z), gelu_erf(v.w)); }
