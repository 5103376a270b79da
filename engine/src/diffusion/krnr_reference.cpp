#include "diffusion/krnr_reference.hpp"

#include <cmath>
#include <string>

#include "dvs/error.hpp"

namespace dvs::diffusion::reference {

namespace {

void check_alpha(double alpha_cumprod) {
  if (!(alpha_cumprod >= 0.0 && alpha_cumprod <= 1.0))
    throw Error("K-RNR: alpha_cumprod must lie in [0, 1] (got " + std::to_string(alpha_cumprod) + ")");
}

void check_same_size(std::span<const float> a, std::span<const float> b, const char* what) {
  if (a.size() != b.size())
    throw Error(std::string("K-RNR: ") + what + " sizes differ (" + std::to_string(a.size()) + " vs " +
                std::to_string(b.size()) + ")");
}

}  // namespace

RnrCoefficients krnr_closed_form(double alpha_cumprod, double k) {
  check_alpha(alpha_cumprod);
  if (!(k >= 0.0)) throw Error("K-RNR: order k must be >= 0 (got " + std::to_string(k) + ")");
  const double a = std::sqrt(alpha_cumprod), b = std::sqrt(1.0 - alpha_cumprod);
  const double n = std::pow(b, k);
  const double m = b == 1.0 ? a * k : a * (1.0 - n) / (1.0 - b);
  return {m, n};
}

RnrCoefficients krnr_series(double alpha_cumprod, int k) {
  check_alpha(alpha_cumprod);
  if (k < 0) throw Error("K-RNR: order k must be >= 0 (got " + std::to_string(k) + ")");
  const double a = std::sqrt(alpha_cumprod), b = std::sqrt(1.0 - alpha_cumprod);
  double m = 0;
  for (int i = 0; i < k; ++i) m += a * std::pow(b, i);
  return {m, std::pow(b, k)};
}

std::vector<float> combine(std::span<const float> x0, std::span<const float> eps, RnrCoefficients c) {
  check_same_size(x0, eps, "x0 and eps");
  std::vector<float> out(x0.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = float(c.m * double(x0[i]) + c.n * double(eps[i]));
  return out;
}

std::vector<float> krnr(std::span<const float> x0, std::span<const float> eps_inv, double alpha_cumprod, double k) {
  return combine(x0, eps_inv, krnr_closed_form(alpha_cumprod, k));
}

std::vector<float> krnr_recursion(std::span<const float> x0, std::span<const float> eps_inv, double alpha_cumprod, int k) {
  check_alpha(alpha_cumprod);
  check_same_size(x0, eps_inv, "x0 and eps_inv");
  if (k < 0) throw Error("K-RNR: order k must be >= 0 (got " + std::to_string(k) + ")");
  const double a = std::sqrt(alpha_cumprod), b = std::sqrt(1.0 - alpha_cumprod);
  std::vector<float> out(x0.size());
  for (size_t i = 0; i < out.size(); ++i) {
    double e = eps_inv[i];
    for (int j = 0; j < k; ++j) e = a * double(x0[i]) + b * e;
    out[i] = float(e);
  }
  return out;
}

std::vector<float> adain_per_channel(std::span<const float> content, std::span<const float> style, LatentShape s,
                                     double eps) {
  check_same_size(content, style, "AdaIN content and style");
  if (s.frames < 1 || s.channels < 1 || s.height < 1 || s.width < 1 || int64_t(content.size()) != s.numel())
    throw Error("AdaIN: shape " + std::to_string(s.frames) + "x" + std::to_string(s.channels) + "x" +
                std::to_string(s.height) + "x" + std::to_string(s.width) + " does not match " +
                std::to_string(content.size()) + " elements");
  if (!(eps >= 0.0)) throw Error("AdaIN: eps must be >= 0");
  const int64_t plane = s.height * s.width, count = s.frames * plane;
  std::vector<float> out(content.size());
  for (int64_t c = 0; c < s.channels; ++c) {
    auto stats = [&](std::span<const float> v) {
      double sum = 0;
      for (int64_t f = 0; f < s.frames; ++f)
        for (int64_t p = 0; p < plane; ++p) sum += v[size_t((f * s.channels + c) * plane + p)];
      const double mean = sum / double(count);
      double sq = 0;
      for (int64_t f = 0; f < s.frames; ++f)
        for (int64_t p = 0; p < plane; ++p) {
          const double d = v[size_t((f * s.channels + c) * plane + p)] - mean;
          sq += d * d;
        }
      return std::pair<double, double>{mean, std::sqrt(sq / double(count) + eps)};
    };
    const auto [mc, sc] = stats(content);
    const auto [ms, ss] = stats(style);
    if (sc == 0.0) throw Error("AdaIN: channel " + std::to_string(c) + " of the content is constant and eps = 0");
    for (int64_t f = 0; f < s.frames; ++f)
      for (int64_t p = 0; p < plane; ++p) {
        const size_t i = size_t((f * s.channels + c) * plane + p);
        out[i] = float((double(content[i]) - mc) / sc * ss + ms);
      }
  }
  return out;
}

std::vector<float> adaptive_krnr_paper(std::span<const float> x0, std::span<const float> eps_inv, LatentShape shape,
                                       double alpha_cumprod, double k, double delta, double eps) {
  const std::vector<float> eps_k = krnr(x0, eps_inv, alpha_cumprod, k);
  const std::vector<float> eps_d = krnr(x0, eps_inv, alpha_cumprod, delta);
  return adain_per_channel(eps_k, eps_d, shape, eps);
}

std::vector<float> adaptive_krnr_official_round(std::span<const float> x0, std::span<const float> eps,
                                                std::span<const float> mu, std::span<const float> sigma,
                                                double alpha_cumprod, int k, int delta) {
  check_same_size(x0, eps, "x0 and eps");
  check_same_size(x0, mu, "x0 and the posterior mean");
  check_same_size(x0, sigma, "x0 and the posterior std");
  const RnrCoefficients ck = krnr_series(alpha_cumprod, k), cd = krnr_series(alpha_cumprod, delta);
  std::vector<float> out(x0.size());
  for (size_t i = 0; i < out.size(); ++i) {
    const double e = eps[i];
    const double noisy = ck.m * x0[i] + ck.n * e;
    const double cur_mean = ck.m * mu[i] + ck.n * e;
    const double cur_std = ck.m * sigma[i];
    const double tgt_mean = cd.m * mu[i] + cd.n * e;
    const double tgt_std = cd.m * sigma[i];
    out[i] = float((noisy - cur_mean) / (cur_std + 1e-9) * tgt_std + tgt_mean);
  }
  return out;
}

std::vector<float> adaptive_krnr_official(std::span<const float> x0, std::span<const float> eps_inv,
                                          std::span<const float> mu, std::span<const float> sigma,
                                          double alpha_cumprod, int k, int delta, int rounds) {
  if (rounds < 0) throw Error("K-RNR: rounds must be >= 0");
  std::vector<float> eps(eps_inv.begin(), eps_inv.end());
  for (int r = 0; r < rounds; ++r) eps = adaptive_krnr_official_round(x0, eps, mu, sigma, alpha_cumprod, k, delta);
  return eps;
}

}  // namespace dvs::diffusion::reference
