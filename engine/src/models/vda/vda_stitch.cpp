// Built with -ffp-contract=off (CMakeLists.txt): every product and sum here is rounded to float32 on its own, as
// numpy computes them; a fused multiply-add would move the alignment by an ulp on ARM and other FMA targets.
#include "models/vda/vda_stitch.hpp"

#include <algorithm>
#include <string>

#include "dvs/error.hpp"

namespace dvs {
namespace {

// x * scale + shift, then negatives set to 0 (NaN stays NaN, as `new_depth[new_depth < 0] = 0`).
std::vector<float> align(const std::vector<float>& x, float scale, float shift) {
  std::vector<float> out(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    const float product = x[i] * scale;
    const float v = product + shift;
    out[i] = v < 0.0f ? 0.0f : v;
  }
  return out;
}

void check_constants(const VdaConfig& c) {
  const std::string why = "Video-Depth-Anything config (" + c.origin + "): ";
  if (c.infer_len < 1 || c.overlap < 0 || c.overlap >= c.infer_len)
    throw Error(why + "inference.overlap must be in [0, infer_len)");
  if (int(c.keyframes.size()) != c.overlap)
    throw Error(why + "inference.keyframes must list exactly `overlap` (" + std::to_string(c.overlap) + ") positions");
  if (c.interp_len < 2 || c.interp_len >= c.overlap)  // the reference needs >= 1 key frame to align on
    throw Error(why + "inference.interp_len must be at least 2 and less than overlap");
}

}  // namespace

std::vector<std::vector<int64_t>> vda_window_frames(int64_t frames, const VdaConfig& cfg) {
  check_constants(cfg);
  if (frames < 1) throw Error("depth: the clip has no frames");
  const int64_t step = cfg.infer_len - cfg.overlap;
  std::vector<std::vector<int64_t>> windows;
  for (int64_t start = 0; start < frames; start += step) {
    std::vector<int64_t> w(size_t(cfg.infer_len));
    for (int64_t i = 0; i < cfg.infer_len; ++i) w[size_t(i)] = std::min(start + i, frames - 1);  // padding: last frame
    if (!windows.empty())
      for (int i = 0; i < cfg.overlap; ++i) w[size_t(i)] = windows.back()[size_t(cfg.keyframes[size_t(i)])];
    windows.push_back(std::move(w));
  }
  return windows;
}

float numpy_pairwise_sum(std::span<const float> v) {
  const size_t n = v.size();
  if (n < 8) {
    float r = 0.0f;
    for (float x : v) r += x;
    return r;
  }
  if (n <= 128) {
    float r[8];
    for (size_t j = 0; j < 8; ++j) r[j] = v[j];
    size_t i = 8;
    for (; i < n - n % 8; i += 8)
      for (size_t j = 0; j < 8; ++j) r[j] += v[i + j];
    float res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) res += v[i];
    return res;
  }
  size_t half = n / 2;
  half -= half % 8;
  return numpy_pairwise_sum(v.subspan(0, half)) + numpy_pairwise_sum(v.subspan(half));
}

std::array<float, 2> vda_scale_shift(std::span<const float> p, std::span<const float> t) {
  if (p.size() != t.size()) throw Error("internal: vda_scale_shift with " + std::to_string(p.size()) + " predictions and " +
                                        std::to_string(t.size()) + " targets");
  std::vector<float> pp(p.size()), pt(p.size()), ones(p.size(), 1.0f);
  for (size_t i = 0; i < p.size(); ++i) {
    pp[i] = p[i] * p[i];  // mask * prediction * prediction with mask 1
    pt[i] = p[i] * t[i];
  }
  const float a00 = numpy_pairwise_sum(pp), a01 = numpy_pairwise_sum(p), a11 = numpy_pairwise_sum(ones);
  const float b0 = numpy_pairwise_sum(pt), b1 = numpy_pairwise_sum(t);
  const float d1 = a00 * a11, d2 = a01 * a01;
  const float det = d1 - d2;
  if (det == 0.0f) return {1.0f, 0.0f};
  const float s1 = a11 * b0, s2 = a01 * b1, t1 = -a01 * b0, t2 = a00 * b1;
  return {(s1 - s2) / det, (t1 + t2) / det};
}

VdaStitcher::VdaStitcher(const VdaConfig& cfg, int64_t frame_pixels) : cfg_(cfg), pixels_(frame_pixels) {
  check_constants(cfg);
}

void VdaStitcher::add_window(std::vector<std::vector<float>> d) {
  if (int64_t(d.size()) != cfg_.infer_len)
    throw Error("internal: a depth window of " + std::to_string(d.size()) + " frames, expected " +
                std::to_string(cfg_.infer_len));
  for (const auto& f : d)
    if (int64_t(f.size()) != pixels_) throw Error("internal: a depth frame of the wrong size");
  const int align_len = cfg_.overlap - cfg_.interp_len;
  if (aligned_.empty()) {
    for (int k = 0; k < align_len; ++k) reference_.push_back(d[size_t(cfg_.keyframes[size_t(k)])]);
    aligned_ = std::move(d);
    return;
  }
  float scale = 1.0f, shift = 0.0f;
  if (!cfg_.metric) {  // metric checkpoints: scale 1, shift 0
    std::vector<float> current, reference;
    for (int k = 0; k < align_len; ++k) {
      current.insert(current.end(), d[size_t(k)].begin(), d[size_t(k)].end());
      reference.insert(reference.end(), reference_[size_t(k)].begin(), reference_[size_t(k)].end());
    }
    const auto st = vda_scale_shift(current, reference);
    scale = st[0], shift = st[1];
  }
  scale_shift_.push_back({scale, shift});
  // Positions align_len..overlap-1 blend into the last interp_len frames: out = old*(1-w) + new*w, w = 0 .. 1 in
  // interp_len steps (Python doubles, rounded to float32 as numpy casts a Python scalar).
  const double step = 1.0 / double(cfg_.interp_len - 1);
  for (int i = 0; i < cfg_.interp_len; ++i) {
    const double w = i == 0 ? 0.0 : i == cfg_.interp_len - 1 ? 1.0 : i * step;
    const float keep = float(1.0 - w), take = float(w);
    std::vector<float>& old = aligned_[aligned_.size() - size_t(cfg_.interp_len) + size_t(i)];
    const std::vector<float> post = align(d[size_t(align_len + i)], scale, shift);
    for (int64_t p = 0; p < pixels_; ++p) {
      const float a = old[size_t(p)] * keep, b = post[size_t(p)] * take;
      old[size_t(p)] = a + b;
    }
  }
  for (int i = cfg_.overlap; i < cfg_.infer_len; ++i) aligned_.push_back(align(d[size_t(i)], scale, shift));
  reference_.resize(std::min<size_t>(reference_.size(), 1));
  for (int k = 1; k < align_len; ++k) reference_.push_back(align(d[size_t(cfg_.keyframes[size_t(k)])], scale, shift));
}

HostTensor VdaStitcher::finish(int64_t frames, int64_t height, int64_t width) const {
  if (height * width != pixels_ || frames > int64_t(aligned_.size()))
    throw Error("internal: VdaStitcher::finish for " + std::to_string(frames) + " frames of " + std::to_string(height) +
                "x" + std::to_string(width));
  HostTensor out({frames, height, width}, DType::f32);
  float* dst = out.as<float>();
  for (int64_t f = 0; f < frames; ++f) std::copy(aligned_[size_t(f)].begin(), aligned_[size_t(f)].end(), dst + f * pixels_);
  return out;
}

}  // namespace dvs
