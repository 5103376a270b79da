// Splat renderer throughput (geometry/splat.hpp) at the official warp size 576×1024: ms per frame and
// points per second, for the float-atomics path, the fixed-point path and the hard z-buffer point mode,
// plus the whole host-to-host render_clip (uploads and downloads included).
#include <cmath>
#include <random>
#include <string>

#include "geometry/splat.hpp"
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
  Tensor t_T = Tensor::upload(ctx, transforms_to_host(tr, 0, F));
  Tensor t_render = Tensor::empty(ctx, {F, 3, H, W}, DType::f32), t_mask = Tensor::empty(ctx, {F, H, W}, DType::f32);
  const double points = double(F) * H * W;
  const std::string shape = std::to_string(F) + "x576x1024";

  struct Variant {
    const char* name;
    SplatOptions o;
  };
  std::vector<Variant> variants;
  if (ctx.caps().float32_atomic_add) variants.push_back({"splat_soft_float_atomics", {}});
  variants.push_back({"splat_soft_fixed_point", {SplatMode::soft_bilinear, SplatAtomics::fixed_point}});
  variants.push_back({"splat_hard_zbuffer", {SplatMode::hard_point}});
  for (const auto& v : variants) {
    SplatRenderer r(ctx, H, W, F, v.o);
    vk::Recorder rec(ctx);
    rec.begin();
    r.record(rec, t_rgb, t_depth, t_T, K, K, t_render, t_mask);
    rec.end();
    double ms = Bench::time_ms([&] { rec.submit(); }, b.quick() ? 0.3 : 1.0);
    char note[128];
    std::snprintf(note, sizeof note, "%.2f ms/frame, %.1f Mpoints/s (device, recorded once)", ms / F, points / (ms * 1e3));
    b.report({v.name, shape, ms, 0, 0, note});
  }
  double ms = Bench::time_ms([&] { render_clip(ctx, rgb, depth, tr, K); }, b.quick() ? 0.3 : 1.0);
  char note[128];
  std::snprintf(note, sizeof note, "%.2f ms/frame, %.1f Mpoints/s (host to host, uploads included)", ms / F,
                points / (ms * 1e3));
  b.report({"render_clip", shape, ms, 0, 0, note});
}

Registration reg("render", 10, render);

}  // namespace
}  // namespace dvs::bench
