// Splat renderer throughput (geometry/splat.hpp) at the official warp size 576×1024: ms per frame and
// points per second, for the float-atomics path, the fixed-point path and the hard z-buffer point mode,
// plus the whole host-to-host render_clip (uploads and downloads included).
#include <cmath>
#include <random>
#include <string>

#include "geometry/splat.hpp"
#include "geometry/synthetic_scene.hpp"
#include "io/depth.hpp"
#include "harness.hpp"
#include "vk/context.hpp"
#include "vk/transfer.hpp"

namespace dvs::bench {
namespace {

using namespace dvs::geometry;

void render(Bench& b) {
  vk::Context& ctx = b.ctx();
  const int H = 576, W = 1024, F = b.quick() ? 2 : 4;
  const Intrinsics K = Intrinsics::official_default(W, H);
  HostTensor rgb({F, 3, H, W}, DType::f32), depth({F, H, W}, DType::f32);
  std::mt19937 g(1);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (int64_t i = 0; i < rgb.numel(); ++i) rgb.as<float>()[i] = u(g);
  // A slanted floor rising to a back wall, with a box in front: realistic depth ranges and occlusions.
  for (int f = 0; f < F; ++f)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        float z = y > H / 2 ? std::min(8.f, 2.f + 6.f * float(H - y) / float(H / 2)) : 8.f;
        if (x > 400 + 10 * f && x < 600 + 10 * f && y > 200 && y < 420) z = 3.f;
        depth.as<float>()[(size_t(f) * H + y) * W + x] = z;
      }
  Trajectory tr = load_trajectory("loop1", 49, official_radius(8.0));
  tr.transforms.erase(tr.transforms.begin(), tr.transforms.begin() + 20);  // frames with real motion
  tr.transforms.resize(size_t(F));

  Tensor t_rgb = Tensor::upload(ctx, rgb), t_depth = Tensor::upload(ctx, depth);
  Tensor t_render = Tensor::empty(ctx, {F, 3, H, W}, DType::f32), t_mask = Tensor::empty(ctx, {F, H, W}, DType::f32);
  const double points = double(F) * H * W;
  const std::string shape = std::to_string(F) + "x576x1024";

  struct Variant {
    const char* name;
    SplatOptions o;
  };
  std::vector<Variant> variants;
  if (ctx.caps().float32_atomic_add)
    variants.push_back({"splat_soft_float_atomics", {SplatMode::soft_bilinear, SplatAtomics::float_atomics}});
  variants.push_back({"splat_soft_fixed_point", {SplatMode::soft_bilinear, SplatAtomics::fixed_point}});
  variants.push_back({"splat_hard_zbuffer", {SplatMode::hard_point}});
  for (const auto& v : variants) {
    SplatRenderer r(ctx, H, W, F, v.o);
    vk::Recorder rec(ctx);
    rec.begin();
    r.record(rec, t_rgb, t_depth, tr.transforms, K, K, t_render, t_mask);
    rec.end();
    double ms = Bench::time_ms([&] { rec.submit(); }, b.quick() ? 0.3 : 1.0);
    char note[128];
    std::snprintf(note, sizeof note, "%.2f ms/frame, %.1f Mpoints/s (device, recorded once)", ms / F, points / (ms * 1e3));
    b.report({v.name, shape, ms, 0, 0, note});
  }
  // Preview size (interactive use): 240×360 soft splat, device time per frame.
  {
    const int h = 240, w = 360;
    HostTensor prgb({F, 3, h, w}, DType::f32);
    for (int64_t i = 0; i < prgb.numel(); ++i) prgb.as<float>()[i] = u(g);
    HostTensor pdepth = resize_depth(depth, h, w);
    Tensor p_rgb = Tensor::upload(ctx, prgb), p_depth = Tensor::upload(ctx, pdepth);
    Tensor p_render = Tensor::empty(ctx, {F, 3, h, w}, DType::f32), p_mask = Tensor::empty(ctx, {F, h, w}, DType::f32);
    const Intrinsics pk = Intrinsics::official_default(w, h);
    SplatRenderer r(ctx, h, w, F);
    vk::Recorder rec(ctx);
    rec.begin();
    r.record(rec, p_rgb, p_depth, tr.transforms, pk, pk, p_render, p_mask);
    rec.end();
    double pms = Bench::time_ms([&] { rec.submit(); }, b.quick() ? 0.3 : 1.0);
    char pnote[128];
    std::snprintf(pnote, sizeof pnote, "%.2f ms/frame = %.1f frames/s, %.1f Mpoints/s (preview size)", pms / F,
                  1000.0 * F / pms, double(F) * h * w / (pms * 1e3));
    b.report({"splat_soft_preview", std::to_string(F) + "x240x360", pms, 0, 0, pnote});
  }
  double ms = Bench::time_ms([&] { render_clip(ctx, rgb, depth, tr, K); }, b.quick() ? 0.3 : 1.0);
  char note[128];
  std::snprintf(note, sizeof note, "%.2f ms/frame, %.1f Mpoints/s (host to host, uploads included)", ms / F,
                points / (ms * 1e3));
  b.report({"render_clip", shape, ms, 0, 0, note});
}

// Accuracy on the synthetic scene: PSNR of the render against the exactly ray-cast novel view, on pixels
// the render marks visible (peak-to-peak 2 for RGB in [−1, 1]), per preset.
void synthetic_psnr(Bench& b) {
  SyntheticSceneSpec spec;
  spec.frames = b.quick() ? 4 : 7;
  spec.height = 288;
  spec.width = 512;
  spec.K = Intrinsics::official_default(spec.width, spec.height);
  RgbdClip src = render_synthetic(spec);
  const size_t HW = size_t(spec.height) * size_t(spec.width);
  const double radius = official_radius(src.depth.as<float>()[size_t(spec.height / 2) * spec.width + size_t(spec.width / 2)]);
  std::vector<std::string> presets = official_preset_names();
  for (const auto& n : canonical_preset_names()) presets.push_back(n);
  for (const auto& name : presets) {
    Trajectory tr = load_trajectory(name, spec.frames, radius);
    RgbdClip gt = render_synthetic(spec, tr);
    double ms = 0;
    RenderedClip r;
    ms = Bench::time_ms([&] { r = render_clip(b.ctx(), src.rgb, src.depth, tr, spec.K); }, 0.0);
    double se = 0;
    int64_t n = 0, visible = 0;
    for (size_t f = 0; f < size_t(spec.frames); ++f)
      for (size_t i = 0; i < HW; ++i) {
        if (r.mask.as<float>()[f * HW + i] == 0.f || gt.valid.as<float>()[f * HW + i] == 0.f) continue;
        ++visible;
        for (size_t c = 0; c < 3; ++c) {
          double d = r.render.as<float>()[(f * 3 + c) * HW + i] - gt.rgb.as<float>()[(f * 3 + c) * HW + i];
          se += d * d;
          ++n;
        }
      }
    char note[160];
    std::snprintf(note, sizeof note, "PSNR %.2f dB on visible pixels (%.1f%% visible), synthetic scene",
                  10 * std::log10(4.0 / std::max(se / double(std::max<int64_t>(n, 1)), 1e-20)),
                  100.0 * double(visible) / double(HW * size_t(spec.frames)));
    b.report({"psnr_" + name, std::to_string(spec.frames) + "x288x512", ms, 0, 0, note});
  }
}

void render_all(Bench& b) {
  render(b);
  synthetic_psnr(b);
}

Registration reg("render", 10, render_all);

}  // namespace
}  // namespace dvs::bench
