#version 450
#extension GL_GOOGLE_include_directive : require
// One round of the official "adaptive K-RNR" (docs/design.md §6.6): per element, with the VAE
// posterior mean μ and std σ (both already ×0.7),
//   noisy = m_k·x0 + n_k·ε,  cur_mean = m_k·μ + n_k·ε,  cur_std = m_k·σ,
//   tgt_mean = m_δ·μ + n_δ·ε, tgt_std = m_δ·σ,  out = (noisy − cur_mean)/(cur_std + 1e-9)·tgt_std + tgt_mean.
layout(local_size_x = 64) in;
#include "index.glsl"

layout(std430, binding = 0) readonly buffer X0 { float x0[]; };
layout(std430, binding = 1) readonly buffer Eps { float eps[]; };
layout(std430, binding = 2) readonly buffer Mu { float mu[]; };
layout(std430, binding = 3) readonly buffer Sigma { float sigma[]; };
layout(std430, binding = 4) writeonly buffer Out { float y[]; };
layout(push_constant) uniform Push { uint n; float m_k; float n_k; float m_d; float n_d; } p;

void main() {
  uint i = flat_index();
  if (i >= p.n) return;
  float e = eps[i];
  float noisy = p.m_k * x0[i] + p.n_k * e;
  float cur_mean = p.m_k * mu[i] + p.n_k * e;
  float cur_std = p.m_k * sigma[i];
  float tgt_mean = p.m_d * mu[i] + p.n_d * e;
  float tgt_std = p.m_d * sigma[i];
  y[i] = (noisy - cur_mean) / (cur_std + 1e-9) * tgt_std + tgt_mean;
}
