// Stochastic Latent Modulation: the latent masks against plain C++ references of the footprint rules (paper)
// and of downsize_mask (official), and the sampling against a host replay of its Philox contract plus its
// properties (only targets change, only to values of their pool, a seed reproduces bit for bit).
// Shapes: Fp = 9 pixel frames of 32x48 -> 3 latent frames of 4x6 cells, C = 4.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "diffusion/slm.hpp"
#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/philox.hpp"

namespace dvs {
namespace {

using diffusion::SlmOptions;

constexpr int kFp = 9, kH = 32, kW = 48, kFl = 3, kLh = 4, kLw = 6, kC = 4;
constexpr int kCells = kFl * kLh * kLw;

class Slm : public test::GpuTest {};

HostTensor pixel_tensor(const std::vector<float>& v) {
  return HostTensor::from_f32({kFp, kH, kW}, v);
}
float& at(std::vector<float>& v, int f, int y, int x) { return v[(size_t(f) * kH + y) * kW + x]; }

// Latent frame f's pixel frames.
std::vector<int> frames_of(int f) {
  if (f == 0) return {0};
  return {4 * f - 3, 4 * f - 2, 4 * f - 1, 4 * f};
}

// A mask with holes in odd places: single pixels at footprint corners, a frame-0-only hole, a block spanning
// cells, a fractional value, a hole in a pixel frame that only latent frame 2 sees.
std::vector<float> odd_mask() {
  std::vector<float> m(size_t(kFp) * kH * kW, 1.0f);
  at(m, 0, 0, 0) = 0;      // latent frame 0, cell (0,0)
  at(m, 0, 31, 47) = 0;    // latent frame 0, last cell, last pixel
  at(m, 4, 15, 47) = 0;    // frame 4 -> latent frame 1, cell (1,5)
  at(m, 5, 8, 8) = 0;      // frame 5 -> latent frame 2, cell (1,1)
  at(m, 8, 23, 16) = 0.5f; // fractional visibility -> latent frame 2, cell (2,2)
  for (int f = 1; f <= 3; ++f)
    for (int y = 12; y < 30; ++y)
      for (int x = 20; x < 37; ++x) at(m, f, y, x) = 0;  // a block in latent frame 1 only
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < 9; ++x) at(m, 6, y, x) = 0;  // left band of frame 6 (latent frame 2)
  return m;
}

// Metric depth: far background (z = 10) with a near object (z = 1) moving right.
std::vector<float> object_depth() {
  std::vector<float> d(size_t(kFp) * kH * kW, 10.0f);
  for (int f = 0; f < kFp; ++f)
    for (int y = 0; y < 16; ++y)
      for (int x = 2 * f; x < 2 * f + 16; ++x) at(d, f, y, x) = 1.0f;
  return d;
}

struct PaperRef {
  std::vector<double> holes, bg;
  std::vector<uint8_t> occluded, source;
  bool fell_back = false;
};

// Plain reference of the paper's footprint rules (double).
PaperRef paper_reference(const std::vector<float>& mask, const std::vector<float>* depth, bool metric,
                         const SlmOptions& o) {
  PaperRef r;
  r.holes.resize(kCells);
  r.bg.resize(kCells);
  r.occluded.resize(kCells);
  r.source.resize(kCells);
  std::vector<double> fmax(kFp, 0.0);
  auto disp = [&](float v) -> double { return metric ? (v > 0 ? 1.0 / v : 0.0) : (v > 0 ? v : 0.0); };
  if (depth)
    for (int f = 0; f < kFp; ++f)
      for (int i = 0; i < kH * kW; ++i) fmax[f] = std::max(fmax[f], disp((*depth)[size_t(f) * kH * kW + i]));
  bool any_source = false;
  for (int f = 0; f < kFl; ++f)
    for (int h = 0; h < kLh; ++h)
      for (int w = 0; w < kLw; ++w) {
        double holes = 0, bg = 0;
        int n = 0;
        for (int pf : frames_of(f))
          for (int y = 8 * h; y < 8 * h + 8; ++y)
            for (int x = 8 * w; x < 8 * w + 8; ++x) {
              const size_t i = (size_t(pf) * kH + y) * kW + x;
              holes += 1.0 - std::clamp(double(mask[i]), 0.0, 1.0);
              if (depth && fmax[pf] > 0) bg += disp((*depth)[i]) / fmax[pf];
              ++n;
            }
        const int c = (f * kLh + h) * kLw + w;
        r.holes[c] = holes / n;
        r.bg[c] = bg / n;
        r.occluded[c] = r.holes[c] > o.hole_threshold;
        r.source[c] = !r.occluded[c] && (!depth || r.bg[c] < o.background_threshold);
        any_source |= r.source[c] != 0;
      }
  if (!any_source) {
    r.fell_back = true;
    for (int c = 0; c < kCells; ++c) r.source[c] = 1 - r.occluded[c];
  }
  return r;
}

// Plain reference of downsize_mask: temporal pair means, then three stages of zero pad (right, bottom) by 1
// and 3x3 average pooling with stride 2 (the zeros count).
std::vector<double> downsize_reference(const std::vector<float>& mask) {
  std::vector<double> out;
  for (int f = 0; f < kFl; ++f) {
    std::vector<double> img(size_t(kH) * kW);
    for (int i = 0; i < kH * kW; ++i) {
      auto px = [&](int pf) { return double(mask[size_t(pf) * kH * kW + i]); };
      img[i] = f == 0 ? px(0) : ((px(4 * f - 3) + px(4 * f - 2)) / 2 + (px(4 * f - 1) + px(4 * f)) / 2) / 2;
    }
    int h = kH, w = kW;
    for (int stage = 0; stage < 3; ++stage) {
      const int ph = h + 1, pw = w + 1;  // padded
      const int oh = (ph - 3) / 2 + 1, ow = (pw - 3) / 2 + 1;
      std::vector<double> next(size_t(oh) * ow);
      for (int i = 0; i < oh; ++i)
        for (int j = 0; j < ow; ++j) {
          double s = 0;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) {
              const int y = 2 * i + a, x = 2 * j + b;
              if (y < h && x < w) s += img[size_t(y) * w + x];
            }
          next[size_t(i) * ow + j] = s / 9;
        }
      img = std::move(next);
      h = oh;
      w = ow;
    }
    EXPECT_EQ(h, kLh);
    EXPECT_EQ(w, kLw);
    out.insert(out.end(), img.begin(), img.end());
  }
  return out;
}

TEST_F(Slm, PaperMasksMatchFootprintReference) {
  const std::vector<float> mask = odd_mask(), depth = object_depth();
  for (float hole_threshold : {0.0f, 0.1f}) {
    SlmOptions o;
    o.hole_threshold = hole_threshold;
    const HostTensor mt = pixel_tensor(mask), dt = pixel_tensor(depth);
    const auto m = diffusion::compute_slm_masks(ctx(), mt, &dt, true, kFl, o);
    const PaperRef r = paper_reference(mask, &depth, true, o);
    ASSERT_EQ(m.frames, kFl);
    ASSERT_EQ(m.height, kLh);
    ASSERT_EQ(m.width, kLw);
    EXPECT_FALSE(m.source_fell_back);
    int occluded = 0, sources = 0;
    for (int c = 0; c < kCells; ++c) {
      EXPECT_NEAR(m.hole_fraction[c], r.holes[c], 1e-6) << "cell " << c;
      EXPECT_NEAR(m.background_mean[c], r.bg[c], 1e-5) << "cell " << c;
      EXPECT_EQ(m.x0_target[c], r.occluded[c]) << "cell " << c << " threshold " << hole_threshold;
      EXPECT_EQ(m.eps_target[c], r.occluded[c]) << "cell " << c;
      if (std::abs(r.bg[c] - o.background_threshold) > 1e-4) {
        EXPECT_EQ(m.x0_source[c], r.source[c]) << "cell " << c;
      }
      occluded += r.occluded[c];
      sources += r.source[c];
    }
    // The odd placements are all caught at threshold 0: frame-0 corners, the frame-4 edge pixel, the frame-5
    // pixel, the fractional pixel, the block and the band.
    if (hole_threshold == 0.0f) {
      auto cell = [](int f, int h, int w) { return (f * kLh + h) * kLw + w; };
      EXPECT_EQ(m.x0_target[cell(0, 0, 0)], 1);
      EXPECT_EQ(m.x0_target[cell(0, 3, 5)], 1);
      EXPECT_EQ(m.x0_target[cell(0, 1, 5)], 0);  // frame 4 is not in latent frame 0's footprint
      EXPECT_EQ(m.x0_target[cell(1, 1, 5)], 1);
      EXPECT_EQ(m.x0_target[cell(2, 1, 5)], 0);
      EXPECT_EQ(m.x0_target[cell(2, 1, 1)], 1);
      EXPECT_EQ(m.x0_target[cell(2, 2, 2)], 1);
      EXPECT_EQ(m.x0_target[cell(1, 0, 0)], 0);
    }
    EXPECT_EQ(m.eps_source, m.x0_source);
    EXPECT_GT(occluded, 0);
    EXPECT_GT(sources, 0);
  }
}

TEST_F(Slm, PaperMasksFromDisparityAndWithoutDepth) {
  const std::vector<float> mask = odd_mask();
  std::vector<float> disparity = object_depth();
  for (float& v : disparity) v = 1.0f / v;  // the same scene given as disparity
  SlmOptions o;
  const HostTensor mt = pixel_tensor(mask), dt = pixel_tensor(disparity);
  const auto m = diffusion::compute_slm_masks(ctx(), mt, &dt, false, kFl, o);
  const PaperRef r = paper_reference(mask, &disparity, false, o);
  for (int c = 0; c < kCells; ++c) {
    EXPECT_NEAR(m.background_mean[c], r.bg[c], 1e-5) << "cell " << c;
    if (std::abs(r.bg[c] - o.background_threshold) > 1e-4) {
      EXPECT_EQ(m.x0_source[c], r.source[c]) << "cell " << c;
    }
  }
  // The device-tensor entry point (renderer outputs) gives the same masks.
  const Tensor mask_dev = Tensor::upload(ctx(), mt), disp_dev = Tensor::upload(ctx(), dt);
  const auto d = diffusion::compute_slm_masks(ctx(), mask_dev, &disp_dev, false, kFl, o);
  EXPECT_EQ(d.hole_fraction, m.hole_fraction);
  EXPECT_EQ(d.background_mean, m.background_mean);
  EXPECT_EQ(d.x0_target, m.x0_target);
  EXPECT_EQ(d.x0_source, m.x0_source);
  // Without depth D = 1: the source is every visible cell.
  const auto n = diffusion::compute_slm_masks(ctx(), mt, nullptr, false, kFl, o);
  for (int c = 0; c < kCells; ++c) EXPECT_EQ(n.x0_source[c], 1 - n.x0_target[c]);
  EXPECT_FALSE(n.source_fell_back);
}

TEST_F(Slm, PaperFallbackAndNothingVisible) {
  std::vector<float> mask = odd_mask();
  const std::vector<float> near(size_t(kFp) * kH * kW, 2.0f);  // all foreground: D = 0 everywhere
  SlmOptions o;
  const HostTensor dt = pixel_tensor(near);
  const auto m = diffusion::compute_slm_masks(ctx(), pixel_tensor(mask), &dt, true, kFl, o);
  EXPECT_TRUE(m.source_fell_back);
  for (int c = 0; c < kCells; ++c) EXPECT_EQ(m.x0_source[c], 1 - m.x0_target[c]);

  std::vector<float> holes(mask.size(), 1.0f);
  for (int f = 0; f < kFp; ++f)
    for (int y = 3; y < kH; y += 8)
      for (int x = 5; x < kW; x += 8) at(holes, f, y, x) = 0;  // one hole in every cell
  EXPECT_THROW(diffusion::compute_slm_masks(ctx(), pixel_tensor(holes), &dt, true, kFl, o), Error);
  SlmOptions official;
  official.preset = SlmOptions::Preset::official;
  EXPECT_THROW(diffusion::compute_slm_masks(ctx(), pixel_tensor(std::vector<float>(mask.size(), 0.0f)), nullptr,
                                            false, kFl, official),
               Error);
  EXPECT_THROW(diffusion::compute_slm_masks(ctx(), pixel_tensor(mask), nullptr, false, 4, o), Error);  // frames
}

TEST_F(Slm, OfficialMatchesDownsizeMaskReference) {
  std::mt19937 gen(7);
  std::vector<float> mask = odd_mask();
  for (int f = 0; f < kFp; ++f)
    for (int y = 0; y < kH; ++y)
      for (int x = 24; x < kW; ++x)
        if (gen() % 50 == 0) at(mask, f, y, x) = 0;  // scattered holes in the right half
  for (int treshold_idx : {-1, -3, 2}) {
    SlmOptions o;
    o.preset = SlmOptions::Preset::official;
    o.treshold_idx = treshold_idx;
    const auto m = diffusion::compute_slm_masks(ctx(), pixel_tensor(mask), nullptr, false, kFl, o);
    const std::vector<double> ref = downsize_reference(mask);
    std::vector<float> uniq;
    for (double v : ref) uniq.push_back(float(v));
    std::sort(uniq.begin(), uniq.end());
    uniq.erase(std::unique(uniq.begin(), uniq.end()), uniq.end());
    int k = -treshold_idx;
    if (k < 0) k += int(uniq.size());
    ASSERT_LT(k, int(uniq.size()));
    EXPECT_EQ(m.tau, uniq[k]) << "treshold_idx " << treshold_idx;
    for (int c = 0; c < kCells; ++c) {
      EXPECT_NEAR(m.visibility[c], ref[c], 1e-6) << "cell " << c;
      EXPECT_EQ(m.x0_target[c], ref[c] < 1.0 ? 1 : 0) << "cell " << c;
      EXPECT_EQ(m.x0_source[c], 1 - m.x0_target[c]);
      EXPECT_EQ(m.eps_target[c], float(ref[c]) <= uniq[k] ? 1 : 0) << "cell " << c;
      EXPECT_EQ(m.eps_source[c], 1 - m.eps_target[c]);
    }
  }
  // All visible: the zero padding still leaves the last row and column below 1, the rest exactly 1.
  SlmOptions o;
  o.preset = SlmOptions::Preset::official;
  const auto m = diffusion::compute_slm_masks(ctx(), pixel_tensor(std::vector<float>(mask.size(), 1.0f)), nullptr,
                                              false, kFl, o);
  const std::vector<double> ref = downsize_reference(std::vector<float>(mask.size(), 1.0f));
  for (int f = 0; f < kFl; ++f)
    for (int h = 0; h < kLh; ++h)
      for (int w = 0; w < kLw; ++w) {
        const int c = (f * kLh + h) * kLw + w;
        const bool edge = h == kLh - 1 || w == kLw - 1;
        EXPECT_EQ(m.x0_target[c], edge ? 1 : 0) << f << "," << h << "," << w;
        EXPECT_NEAR(m.visibility[c], ref[c], 1e-6);
        if (!edge) {
          EXPECT_EQ(m.visibility[c], 1.0f);
        }
      }
  EXPECT_LT(m.visibility[(kLh - 1) * kLw + kLw - 1], 0.53f);
}

// ---- sampling --------------------------------------------------------------------------------------------

struct CellMasks {
  std::vector<uint8_t> target, source;
};

CellMasks random_cells(uint32_t seed, bool empty_frame1_source) {
  std::mt19937 gen(seed);
  CellMasks m{std::vector<uint8_t>(kCells), std::vector<uint8_t>(kCells)};
  for (int c = 0; c < kCells; ++c) {
    const uint32_t r = gen() % 10;
    m.target[c] = r < 3;
    m.source[c] = r >= 5;
  }
  if (empty_frame1_source)
    for (int c = kLh * kLw; c < 2 * kLh * kLw; ++c) m.source[c] = 0;
  return m;
}

// Latent whose element e holds the value e + 0.25, so a value names the element it came from.
std::vector<float> index_latent() {
  std::vector<float> v(size_t(kCells) * kC);
  for (size_t e = 0; e < v.size(); ++e) v[e] = float(e) + 0.25f;
  return v;
}

std::vector<float> run_slm(vk::Context& ctx, const diffusion::SlmIndexPlan& plan, const ops::RandomStream& rs) {
  const std::vector<float> v = index_latent();
  const Tensor t = Tensor::upload(ctx, HostTensor::from_f32({kFl, kC, kLh, kLw}, v));
  ops::run_now(ctx, [&](vk::Recorder& rec) { diffusion::apply_slm(rec, t, plan, rs); });
  return t.download(ctx).to_f32();
}

// Host replay of the documented contract: targets ascending, pool orders as in slm.hpp/slm.cpp.
std::vector<float> replay(const CellMasks& m, SlmOptions::Scope scope, const ops::RandomStream& rs) {
  const int hw = kLh * kLw;
  std::vector<float> v = index_latent();
  const std::vector<float> orig = v;
  auto pool_of = [&](int f, int c) {
    std::vector<int> pool;
    auto add = [&](int pf, int pc) {
      for (int k = 0; k < hw; ++k)
        if (m.source[pf * hw + k]) pool.push_back((pf * kC + pc) * hw + k);
    };
    if (scope == SlmOptions::Scope::global) {
      for (int pf = 0; pf < kFl; ++pf)
        for (int pc = 0; pc < kC; ++pc) add(pf, pc);
    } else if (scope == SlmOptions::Scope::frame) {
      for (int pc = 0; pc < kC; ++pc) add(f, pc);
      if (pool.empty()) return std::vector<int>();  // caller falls back
    } else {
      add(f, c);
    }
    return pool;
  };
  uint64_t i = 0;
  for (int f = 0; f < kFl; ++f)
    for (int c = 0; c < kC; ++c)
      for (int k = 0; k < hw; ++k) {
        if (!m.target[f * hw + k]) continue;
        std::vector<int> pool = pool_of(f, c);
        if (pool.empty()) {
          if (scope == SlmOptions::Scope::frame) {
            for (int pf = 0; pf < kFl; ++pf)
              for (int pc = 0; pc < kC; ++pc)
                for (int kk = 0; kk < hw; ++kk)
                  if (m.source[pf * hw + kk]) pool.push_back((pf * kC + pc) * hw + kk);
          } else {  // frame_channel: the same channel of every frame
            for (int pf = 0; pf < kFl; ++pf)
              for (int kk = 0; kk < hw; ++kk)
                if (m.source[pf * hw + kk]) pool.push_back((pf * kC + c) * hw + kk);
          }
        }
        const uint32_t u = philox::below(rs.seed, rs.stream, rs.base + i, uint32_t(pool.size()));
        v[(f * kC + c) * hw + k] = orig[pool[u]];
        ++i;
      }
  return v;
}

const SlmOptions::Scope kScopes[] = {SlmOptions::Scope::global, SlmOptions::Scope::frame,
                                     SlmOptions::Scope::frame_channel};

TEST_F(Slm, SamplingMatchesPhiloxReplayBitForBit) {
  for (bool empty_frame : {false, true})
    for (SlmOptions::Scope scope : kScopes) {
      const CellMasks m = random_cells(11, empty_frame);
      const auto plan = diffusion::make_slm_index_plan(ctx(), m.target, m.source, kFl, kLh, kLw, kC, scope, "test");
      const ops::RandomStream rs{0x1234567890abcdefull, 5, (1ull << 32) + 3};  // base crosses 32 bits, skewed
      const std::vector<float> got = run_slm(ctx(), plan, rs), want = replay(m, scope, rs);
      EXPECT_EQ(got, want) << "scope " << int(scope) << " empty frame " << empty_frame;
      if (empty_frame && scope != SlmOptions::Scope::global) {
        EXPECT_GT(plan.fallback_segments, 0);
      } else {
        EXPECT_EQ(plan.fallback_segments, 0);
      }
    }
}

TEST_F(Slm, SamplingProperties) {
  const int hw = kLh * kLw;
  const CellMasks m = random_cells(3, false);
  for (SlmOptions::Scope scope : kScopes) {
    const auto plan = diffusion::make_slm_index_plan(ctx(), m.target, m.source, kFl, kLh, kLw, kC, scope, "test");
    const ops::RandomStream rs{42, diffusion::kSlmStreamX0, 0};
    const std::vector<float> a = run_slm(ctx(), plan, rs), orig = index_latent();
    int changed = 0;
    std::set<int> used;
    for (int e = 0; e < kCells * kC; ++e) {
      const int f = e / (kC * hw), c = (e / hw) % kC, k = e % hw;
      if (!m.target[f * hw + k]) {
        EXPECT_EQ(a[e], orig[e]) << "non-target element " << e << " changed";
        continue;
      }
      const int src = int(a[e]);  // value e' + 0.25 names source element e'
      ASSERT_EQ(float(src) + 0.25f, a[e]);
      const int sf = src / (kC * hw), sc = (src / hw) % kC, sk = src % hw;
      EXPECT_TRUE(m.source[sf * hw + sk]) << "element " << e << " took a non-source value";
      if (scope != SlmOptions::Scope::global) {
        EXPECT_EQ(sf, f);
      }
      if (scope == SlmOptions::Scope::frame_channel) {
        EXPECT_EQ(sc, c);
      }
      changed += a[e] != orig[e];
      used.insert(src);
    }
    EXPECT_EQ(changed, plan.n_targets);  // sources and targets are disjoint: every target changes
    EXPECT_GT(used.size(), size_t(plan.n_targets / 3));  // with replacement, yet spread over the pool
    EXPECT_EQ(run_slm(ctx(), plan, rs), a) << "same seed must reproduce bit for bit";
    EXPECT_NE(run_slm(ctx(), plan, {43, diffusion::kSlmStreamX0, 0}), a) << "another seed";
    EXPECT_NE(run_slm(ctx(), plan, {42, diffusion::kSlmStreamEps, 0}), a) << "another stream";
  }
}

TEST_F(Slm, PlanFromMasksModulatesX0AndEpsIndependently) {
  SlmOptions o;
  const std::vector<float> mask = odd_mask(), depth = object_depth();
  const HostTensor dt = pixel_tensor(depth);
  const auto masks = diffusion::compute_slm_masks(ctx(), pixel_tensor(mask), &dt, true, kFl, o);
  const auto plan = diffusion::make_slm_plan(ctx(), masks, kC, o.scope);
  EXPECT_GT(plan.x0.n_targets, 0);
  const std::vector<float> v = index_latent();
  const Tensor x0 = Tensor::upload(ctx(), HostTensor::from_f32({kFl, kC, kLh, kLw}, v));
  const Tensor eps = Tensor::upload(ctx(), HostTensor::from_f32({kFl, kC, kLh, kLw}, v));
  ops::run_now(ctx(), [&](vk::Recorder& rec) { diffusion::apply_slm(rec, x0, eps, plan, 9, 0); });
  const std::vector<float> a = x0.download(ctx()).to_f32(), b = eps.download(ctx()).to_f32();
  EXPECT_NE(a, b);  // same masks, different streams
  CellMasks cm{masks.x0_target, masks.x0_source};
  EXPECT_EQ(a, replay(cm, o.scope, diffusion::slm_stream(9, false, 0, kCells * kC)));
  EXPECT_EQ(b, replay(cm, o.scope, diffusion::slm_stream(9, true, 0, kCells * kC)));
  // Nothing to do without targets.
  std::vector<uint8_t> none(kCells, 0), all(kCells, 1);
  const auto empty = diffusion::make_slm_index_plan(ctx(), none, all, kFl, kLh, kLw, kC,
                                                    SlmOptions::Scope::global, "empty");
  EXPECT_EQ(run_slm(ctx(), empty, {1, 1, 0}), index_latent());
}

}  // namespace
}  // namespace dvs

namespace dvs {
namespace {

// A clip over one binding: frame maxima in windows of whole frames, footprints in windows of latent frames.
// binding=30KiB holds 5 of the 32x48 frames (6 KiB each): two frame-max windows, one latent frame per
// footprint window (frame 0 alone, then 4 pixel frames each). Both presets, bitwise the unsplit masks.
TEST_F(Slm, MasksOverOneBindingSplitInFrameWindows) {
  const HostTensor mt = pixel_tensor(odd_mask()), dt = pixel_tensor(object_depth());
  for (auto preset : {SlmOptions::Preset::paper, SlmOptions::Preset::official}) {
    SlmOptions o;
    o.preset = preset;
    const auto whole = diffusion::compute_slm_masks(ctx(), mt, &dt, true, kFl, o);
    ctx().reset_splits();
    diffusion::SlmMasks split;
    {
      test::ScopedLimits limits(ctx(), "binding=30KiB");
      split = diffusion::compute_slm_masks(ctx(), mt, &dt, true, kFl, o);
    }
    EXPECT_EQ(ctx().splits().count("slm"), 1u);
    EXPECT_EQ(split.hole_fraction, whole.hole_fraction);
    EXPECT_EQ(split.background_mean, whole.background_mean);
    EXPECT_EQ(split.x0_target, whole.x0_target);
    EXPECT_EQ(split.x0_source, whole.x0_source);
    EXPECT_EQ(split.eps_target, whole.eps_target);
  }
  // Exactly four frames per binding (24 KiB): one latent frame per window.
  {
    SlmOptions o;
    const auto whole = diffusion::compute_slm_masks(ctx(), mt, &dt, true, kFl, o);
    test::ScopedLimits limits(ctx(), "binding=24KiB");
    const auto split = diffusion::compute_slm_masks(ctx(), mt, &dt, true, kFl, o);
    EXPECT_EQ(split.hole_fraction, whole.hole_fraction);
    EXPECT_EQ(split.background_mean, whole.background_mean);
  }
  // Four frames (one latent frame's footprint) must fit one binding: 18 KiB holds three.
  test::ScopedLimits limits(ctx(), "binding=18KiB");
  EXPECT_THROW(diffusion::compute_slm_masks(ctx(), mt, &dt, true, kFl, SlmOptions{}), Error);
}

}  // namespace
}  // namespace dvs
