// The splat renderer against analytic scenes and against a plain C++ port of the official algorithm
// (docs/design.md §6.3). Scenes use f = 64 and power-of-two depths so that projections are exact in
// float and every pixel lands where geometry says.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "dvs/error.hpp"
#include "geometry/splat.hpp"
#include "geometry/synthetic_scene.hpp"
#include "support/gpu.hpp"

namespace dvs::geometry {
namespace {

using test::GpuTest;

Intrinsics exact_camera(int H, int W) {
  Intrinsics k;
  k.fx = k.fy = 64;
  k.cx = 32;
  k.cy = 24;
  k.width = W;
  k.height = H;
  return k;
}

Trajectory constant(const glm::dmat4& T, int frames) {
  Trajectory t;
  t.transforms.assign(size_t(frames), T);
  return t;
}

HostTensor random_rgb(int F, int H, int W, uint32_t seed) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  HostTensor t({F, 3, H, W}, DType::f32);
  for (int64_t i = 0; i < t.numel(); ++i) t.as<float>()[i] = u(g);
  return t;
}

// Plain C++ port of the official splat: its geometry (unprojection, transform, projection) computed in double,
// the exact values any float order of operations approximates (the official code's float32 order misses by a few
// ulps, which the depth weighting can amplify: splat_common.glsl), then the footprint, weights and normalisation
// in float as the official code does them, summed in double.
RenderedClip reference_splat(const HostTensor& rgb, const HostTensor& depth, const Trajectory& tr, const Intrinsics& K,
                             bool keep_behind) {
  const int F = int(depth.shape[0]), H = int(depth.shape[1]), W = int(depth.shape[2]);
  const size_t HW = size_t(H) * size_t(W);
  RenderedClip out{HostTensor({F, 3, H, W}, DType::f32), HostTensor({F, H, W}, DType::f32)};
  for (int f = 0; f < F; ++f) {
    const glm::dmat4& T = tr.transforms[size_t(f)];  // column-major: T[column][row]
    std::vector<float> U(HW), V(HW), Z(HW);
    std::vector<char> used(HW);
    float max_l = 0;
    for (size_t i = 0; i < HW; ++i) {
      const double z = depth.as<float>()[f * HW + i];
      const double x1 = z * ((double(i % W) - K.cx) / K.fx), y1 = z * ((double(i / W) - K.cy) / K.fy), z1 = z;
      const double X = T[0][0] * x1 + T[1][0] * y1 + T[2][0] * z1 + T[3][0];
      const double Y = T[0][1] * x1 + T[1][1] * y1 + T[2][1] * z1 + T[3][1];
      const double Zd = T[0][2] * x1 + T[1][2] * y1 + T[2][2] * z1 + T[3][2];
      U[i] = float(K.fx * X / Zd + K.cx), V[i] = float(K.fy * Y / Zd + K.cy), Z[i] = float(Zd);
      used[i] = keep_behind ? Z[i] != 0 : Z[i] > 0;
      if (used[i]) max_l = std::max(max_l, std::log(1.0f + std::clamp(Z[i], 0.0f, 1000.0f)));
    }
    std::vector<double> acc(HW * 4, 0.0);
    for (size_t i = 0; i < HW; ++i) {
      if (!used[i]) continue;
      const float u = U[i], v = V[i];
      float ox = u + 1, oy = v + 1;
      float fX = std::floor(ox), fY = std::floor(oy), cX = std::ceil(ox), cY = std::ceil(oy);
      auto cl = [](float a, float hi) { return std::clamp(a, 0.0f, hi); };
      float hx = float(W + 1), hy = float(H + 1);
      ox = cl(ox, hx), oy = cl(oy, hy), fX = cl(fX, hx), fY = cl(fY, hy), cX = cl(cX, hx), cY = cl(cY, hy);
      float w[4] = {(1 - (oy - fY)) * (1 - (ox - fX)), (1 - (cY - oy)) * (1 - (ox - fX)), (1 - (oy - fY)) * (1 - (cX - ox)),
                    (1 - (cY - oy)) * (1 - (cX - ox))};
      int px[4] = {int(fX), int(fX), int(cX), int(cX)}, py[4] = {int(fY), int(cY), int(fY), int(cY)};
      float dw = max_l > 0 ? std::exp(std::log(1.0f + std::clamp(Z[i], 0.0f, 1000.0f)) / max_l * 50.0f) : 1.0f;
      for (int k = 0; k < 4; ++k) {
        if (px[k] < 1 || py[k] < 1 || px[k] > W || py[k] > H) continue;  // cropped border
        size_t q = size_t(py[k] - 1) * W + size_t(px[k] - 1);
        double wk = double(w[k] / dw);
        for (int c = 0; c < 3; ++c) acc[q * 4 + c] += wk * rgb.as<float>()[(f * 3 + c) * HW + i];
        acc[q * 4 + 3] += wk;
      }
    }
    for (size_t q = 0; q < HW; ++q) {
      bool hit = acc[q * 4 + 3] > 0;
      for (int c = 0; c < 3; ++c)
        out.render.as<float>()[(f * 3 + c) * HW + q] = hit ? float(std::clamp(acc[q * 4 + c] / acc[q * 4 + 3], -1.0, 1.0)) : -1.f;
      out.mask.as<float>()[f * HW + q] = hit ? 1.f : 0.f;
    }
  }
  return out;
}

struct Diff {
  double max_abs = 0;
  int mask_mismatch = 0;
};

Diff compare(const RenderedClip& a, const RenderedClip& b) {
  Diff d;
  const int64_t F = a.mask.shape[0], HW = a.mask.shape[1] * a.mask.shape[2];
  for (int64_t f = 0; f < F; ++f)
    for (int64_t i = 0; i < HW; ++i) {
      float ma = a.mask.as<float>()[f * HW + i], mb = b.mask.as<float>()[f * HW + i];
      if (ma != mb) {
        ++d.mask_mismatch;
        continue;
      }
      for (int c = 0; c < 3; ++c)
        d.max_abs = std::max(d.max_abs, double(std::abs(a.render.as<float>()[(f * 3 + c) * HW + i] -
                                                         b.render.as<float>()[(f * 3 + c) * HW + i])));
    }
  return d;
}

SplatOptions fixed_point() {
  SplatOptions o;
  o.atomics = SplatAtomics::fixed_point;
  return o;
}

// The float-atomics path where the device has it (an option; the default is fixed point), else the default.
SplatOptions float_path(vk::Context& ctx) {
  SplatOptions o;
  if (ctx.caps().float32_atomic_add) o.atomics = SplatAtomics::float_atomics;
  return o;
}

// Identity trajectory: every pixel lands exactly on itself (weight 4 on its own pixel only) -> the input.
TEST_F(GpuTest, GeometrySplatIdentityReproducesInput) {
  const int F = 2, H = 48, W = 64;
  Intrinsics K = exact_camera(H, W);
  HostTensor rgb = random_rgb(F, H, W, 1);
  HostTensor depth({F, H, W}, DType::f32);
  std::mt19937 g(2);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = float(1 << (g() % 4));  // 1, 2, 4, 8
  for (SplatOptions o : {float_path(ctx()), fixed_point(), SplatOptions{SplatMode::hard_point}}) {
    RenderedClip r = render_clip(ctx(), rgb, depth, constant(glm::dmat4(1.0), F), K, o);
    double err = 0;
    for (int64_t i = 0; i < rgb.numel(); ++i) err = std::max(err, double(std::abs(r.render.as<float>()[i] - rgb.as<float>()[i])));
    for (int64_t i = 0; i < r.mask.numel(); ++i) ASSERT_EQ(r.mask.as<float>()[i], 1.f);
    EXPECT_LE(err, o.atomics != SplatAtomics::float_atomics ? 2e-5 : 1e-6) << "mode " << int(o.mode);
  }
}

// Fronto-parallel plane at z = 4, camera moved right by t: the image shifts left by exactly f·t/z pixels;
// a half-pixel shift blends the two neighbours 50/50 (equal depth -> equal soft weights).
TEST_F(GpuTest, GeometrySplatPlaneTranslationShiftsByFocalTimesTOverZ) {
  const int F = 1, H = 48, W = 64;
  Intrinsics K = exact_camera(H, W);
  HostTensor rgb = random_rgb(F, H, W, 3);
  HostTensor depth({F, H, W}, DType::f32);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = 4.f;
  for (double shift : {5.0, 2.5}) {
    double t = shift * 4.0 / 64.0;  // f·t/z = shift
    for (SplatOptions o : {float_path(ctx()), fixed_point()}) {
      RenderedClip r = render_clip(ctx(), rgb, depth, constant(translation({-t, 0, 0}), F), K, o);
      const int s0 = int(std::floor(shift));
      const bool half = shift != std::floor(shift);
      double err = 0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          bool expect_hit = x + s0 + (half ? 1 : 0) <= W - 1 || (half && x + s0 <= W - 1);
          float m = r.mask.as<float>()[y * W + x];
          ASSERT_EQ(m, expect_hit ? 1.f : 0.f) << "x=" << x << " y=" << y << " shift=" << shift;
          for (int c = 0; c < 3; ++c) {
            float got = r.render.as<float>()[(c * H + y) * W + x];
            float want;
            if (!expect_hit) want = -1.f;
            else if (!half) want = rgb.as<float>()[(c * H + y) * W + x + s0];
            else if (x + s0 + 1 <= W - 1)
              want = 0.5f * (rgb.as<float>()[(c * H + y) * W + x + s0] + rgb.as<float>()[(c * H + y) * W + x + s0 + 1]);
            else want = rgb.as<float>()[(c * H + y) * W + x + s0];
            err = std::max(err, double(std::abs(got - want)));
          }
        }
      EXPECT_LE(err, 1e-4) << "shift " << shift << " fixed=" << (o.atomics != SplatAtomics::float_atomics);
    }
  }
}

// A square at z = 2 in front of a wall at z = 8; the camera moves right by 0.25: the wall shifts by 2 px,
// the square by 8 px, and the wall strip the square hid (plus the right border) becomes a hole.
TEST_F(GpuTest, GeometrySplatObjectDisocclusionMatchesGeometry) {
  const int F = 1, H = 48, W = 64;
  const int x0 = 20, x1 = 40, y0 = 12, y1 = 36, sw = 2, so = 8;
  Intrinsics K = exact_camera(H, W);
  HostTensor rgb({F, 3, H, W}, DType::f32), depth({F, H, W}, DType::f32);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      bool obj = x >= x0 && x < x1 && y >= y0 && y < y1;
      depth.as<float>()[y * W + x] = obj ? 2.f : 8.f;
      for (int c = 0; c < 3; ++c) rgb.as<float>()[(c * H + y) * W + x] = obj ? 0.75f : -0.5f;
    }
  auto predicted_hole = [&](int x, int y) {
    if (x >= W - sw) return true;  // nothing to the right of the source image
    bool in_rows = y >= y0 && y < y1;
    bool hidden_wall = in_rows && x + sw >= x0 && x + sw < x1;  // the wall seen here was behind the square
    bool square = in_rows && x + so >= x0 && x + so < x1;       // the square moved over it
    return hidden_wall && !square;
  };
  for (SplatOptions o : {float_path(ctx()), fixed_point(), SplatOptions{SplatMode::hard_point}}) {
    RenderedClip r = render_clip(ctx(), rgb, depth, constant(translation({-0.25, 0, 0}), F), K, o);
    int inter = 0, uni = 0;
    double colour_err = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        bool hole = r.mask.as<float>()[y * W + x] == 0.f, want = predicted_hole(x, y);
        inter += hole && want;
        uni += hole || want;
        if (!hole && !want) {
          bool square = y >= y0 && y < y1 && x + so >= x0 && x + so < x1;
          colour_err = std::max(colour_err, double(std::abs(r.render.as<float>()[y * W + x] - (square ? 0.75f : -0.5f))));
        }
      }
    ASSERT_GT(uni, 0);
    double iou = double(inter) / uni;
    EXPECT_GE(iou, 0.98) << "mode " << int(o.mode);
    EXPECT_LE(colour_err, 1e-4) << "the near square must win where it overlaps the wall";
  }
}

// Random scene under an official orbit: the GPU equals the C++ port up to summation order.
TEST_F(GpuTest, GeometrySplatMatchesOfficialReference) {
  const int F = 3, H = 37, W = 53;
  Intrinsics K = Intrinsics::official_default(W, H);
  HostTensor rgb = random_rgb(F, H, W, 7);
  HostTensor depth({F, H, W}, DType::f32);
  std::mt19937 g(8);
  std::uniform_real_distribution<float> u(1.f, 12.f);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = u(g);
  Trajectory tr;
  tr.transforms = {official_transform(4, -7, 0.1, 3.0), official_transform(-10, 12, -0.2, 3.0),
                   official_transform(0, 0, 0.0, 3.0) * translation({0.3, -0.2, 0.1})};
  RenderedClip ref = reference_splat(rgb, depth, tr, K, false);
  for (SplatOptions o : {float_path(ctx()), fixed_point()}) {
    bool fixed = o.atomics != SplatAtomics::float_atomics;
    RenderedClip r = render_clip(ctx(), rgb, depth, tr, K, o);
    Diff d = compare(r, ref);
    EXPECT_LE(d.mask_mismatch, 2) << "fixed=" << fixed;
    // Measured on lavapipe: 3.6e-4 / 3.7e-4 (the official float32 order of the projection: 8.2e-3 against this
    // exact geometry, which is why the shader computes the pixel plus its displacement).
    EXPECT_LE(d.max_abs, 5e-4) << "fixed=" << fixed;
  }
}

// Official behaviour for points behind the camera (kept, largest weight) vs the default (dropped).
TEST_F(GpuTest, GeometrySplatPointsBehindCamera) {
  const int F = 1, H = 24, W = 32;
  Intrinsics K = Intrinsics::official_default(W, H);
  HostTensor rgb = random_rgb(F, H, W, 11);
  HostTensor depth({F, H, W}, DType::f32);
  std::mt19937 g(12);
  std::uniform_real_distribution<float> u(0.5f, 4.f);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = u(g);
  Trajectory tr = constant(rotation_y(0.9) * translation({0, 0, -2.0}), F);  // many points end behind
  for (bool keep : {false, true}) {
    SplatOptions o;
    o.keep_points_behind_camera = keep;
    RenderedClip r = render_clip(ctx(), rgb, depth, tr, K, o);
    Diff d = compare(r, reference_splat(rgb, depth, tr, K, keep));
    EXPECT_LE(d.mask_mismatch, 2) << "keep=" << keep;
    EXPECT_LE(d.max_abs, 2e-4) << "keep=" << keep;  // measured 5.1e-5 (the official float32 order: 0.85, 6 masks)
  }
}

// Whole clips go through in chunks; shapes and intrinsics are checked.
TEST_F(GpuTest, GeometrySplatClipValidation) {
  const int F = 2, H = 8, W = 8;
  Intrinsics K = Intrinsics::official_default(W, H);
  HostTensor rgb = random_rgb(F, H, W, 1), depth({F, H, W}, DType::f32);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = 2.f;
  EXPECT_THROW(render_clip(ctx(), rgb, depth, constant(glm::dmat4(1.0), 3), K), Error);
  EXPECT_THROW(render_clip(ctx(), rgb, depth, constant(glm::dmat4(1.0), F), Intrinsics::official_default(16, 8)), Error);
  HostTensor bad_rgb = random_rgb(F, H, W + 1, 1);
  EXPECT_THROW(render_clip(ctx(), bad_rgb, depth, constant(glm::dmat4(1.0), F), K), Error);
  // Frames of 576x1024 take 9 MiB of accumulation each: a 128 MiB binding (lavapipe, the Vulkan minimum)
  // holds 14; under a forced lower limit, as many as fit, and at least one.
  const uint64_t binding = ctx().caps().max_storage_buffer_range, per_frame = 576ull * 1024 * 16;
  const int fit = SplatRenderer::frames_per_binding(ctx(), 576, 1024);
  if (binding >= (128ull << 20)) EXPECT_GE(fit, 13);
  EXPECT_TRUE(uint64_t(fit) * per_frame <= binding || fit == 1) << fit;
}

// Chunked rendering (what a 49-frame 576×1024 clip needs) gives the same frames as one chunk.
TEST_F(GpuTest, GeometrySplatChunksMatchOneChunk) {
  const int F = 5, H = 24, W = 40;
  Intrinsics K = Intrinsics::official_default(W, H);
  HostTensor rgb = random_rgb(F, H, W, 21), depth({F, H, W}, DType::f32);
  std::mt19937 g(22);
  std::uniform_real_distribution<float> u(1.f, 9.f);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = u(g);
  Trajectory tr = load_trajectory("arc_left:10", F, 3.0);
  for (SplatOptions o : {float_path(ctx()), fixed_point(), SplatOptions{SplatMode::hard_point}}) {
    RenderedClip one = render_clip(ctx(), rgb, depth, tr, K, o);
    o.max_chunk_frames = 2;  // chunks of 2, 2, 1
    RenderedClip chunked = render_clip(ctx(), rgb, depth, tr, K, o);
    EXPECT_EQ(chunked.mask.data, one.mask.data);
    Diff d = compare(chunked, one);
    EXPECT_LE(d.max_abs, 1e-6) << "mode " << int(o.mode);
  }
}

}  // namespace
}  // namespace dvs::geometry

namespace dvs::geometry {
namespace {

double psnr_visible(const RenderedClip& r, const RgbdClip& gt, int* counted) {
  const int64_t F = r.mask.shape[0], HW = r.mask.shape[1] * r.mask.shape[2];
  double se = 0;
  int64_t n = 0;
  for (int64_t f = 0; f < F; ++f)
    for (int64_t i = 0; i < HW; ++i) {
      if (r.mask.as<float>()[f * HW + i] == 0.f || gt.valid.as<float>()[f * HW + i] == 0.f) continue;
      for (int c = 0; c < 3; ++c) {
        double d = r.render.as<float>()[(f * 3 + c) * HW + i] - gt.rgb.as<float>()[(f * 3 + c) * HW + i];
        se += d * d;
      }
      n += 3;
    }
  *counted = int(n / 3);
  return 10 * std::log10(4.0 / std::max(se / double(n), 1e-20));  // peak-to-peak 2 for [-1, 1]
}

// The synthetic scene: the source view rendered with the identity is itself; a novel view rendered from
// its RGB-D matches the exactly ray-cast novel view on visible pixels.
using test::GpuTest;

TEST_F(GpuTest, GeometrySplatSyntheticSceneNovelView) {
  SyntheticSceneSpec spec;
  spec.frames = 3;
  spec.height = 48;
  spec.width = 64;
  spec.K = Intrinsics::official_default(64, 48);
  RgbdClip src = render_synthetic(spec);
  for (int64_t i = 0; i < src.valid.numel(); ++i) ASSERT_EQ(src.valid.as<float>()[i], 1.f);
  EXPECT_NEAR(src.depth.as<float>()[0], 6.0f, 1e-5);  // top-left pixel sees the wall
  const float radius = float(official_radius(src.depth.as<float>()[24 * 64 + 32]));
  for (const char* preset : {"truck_right:0.1", "arc_left:6", "dolly_in:0.1"}) {
    Trajectory tr = load_trajectory(preset, spec.frames, radius);
    RgbdClip gt = render_synthetic(spec, tr);
    RenderedClip r = render_clip(ctx(), src.rgb, src.depth, tr, spec.K);
    int counted = 0;
    double psnr = psnr_visible(r, gt, &counted);
    EXPECT_GT(counted, 3 * 48 * 64 * 8 / 10) << preset;
    EXPECT_GE(psnr, 26.0) << preset;  // measured 29–33 dB
  }
}

}  // namespace
}  // namespace dvs::geometry
