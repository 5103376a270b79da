// Golden checks of the CogVideoX 3D causal VAE against the pack (DVS_GOLDEN_DIR): cases vae_encode,
// vae_decode, vae_tiling_disabled_explicit, vae_frame_batching (17 frames: two encode and two decode
// batches with the conv cache), vae_tiled and vae_decode_even_latent (added to our copy of pack A by
// tests/golden_tools/make_vae_even_latent_decode.py with diffusers' own VAE code). Tolerances are the cases.json ones (|ours − golden| ≤
// atol + rtol·|golden|); every check prints the max error it saw. Sizes come from the pack's vae/config.json
// and tiling settings from cases.json, so any pack of this format can be run.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/memory_plan.hpp"
#include "support/gpu.hpp"
#include "support/pack.hpp"
#include "support/precision_rule.hpp"
#include "tensor/dispatch.hpp"
#include "vk/profiler.hpp"

namespace fs = std::filesystem;
using dvs::HostTensor;
using dvs::Tensor;
using dvs::models::CogVideoXVae;

namespace {

fs::path pack() { return dvs::test::golden_path(); }
using Tol = dvs::test::PackTolerance;
using dvs::test::pack_case;
using dvs::test::pack_cases;
using dvs::test::tolerance_of;
HostTensor load(const std::string& rel) { return dvs::test::pack_npy(rel); }

// `got` against the pack file `rel` by the precision rule for convolutions (support/precision_rule.hpp: the
// case's tolerance, or 2x PyTorch's bf16 run under 16-bit-operand kernels); prints both errors.
void expect_close(const std::string& what, const HostTensor& got, const std::string& rel, Tol tol) {
  dvs::test::expect_golden(what, got, rel, tol.atol, tol.rtol, dvs::test::kConvOps);
}

HostTensor divided(const HostTensor& x, float s) {
  std::vector<float> v = x.to_f32();
  for (float& f : v) f = f / s;
  return HostTensor::from_f32(x.shape, v);
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

class VaeGolden : public dvs::test::GpuTest {
 protected:
  CogVideoXVae& vae() {
    if (!vae_) vae_ = std::make_unique<CogVideoXVae>(ctx(), pack() / "model" / "vae");
    return *vae_;
  }
  HostTensor dl(const Tensor& t) { return t.download(ctx()); }
  Tensor up(const HostTensor& h) { return Tensor::upload(ctx(), h, "golden input"); }
  float scaling() { return float(vae().config().scaling_factor); }

 private:
  std::unique_ptr<CogVideoXVae> vae_;
};

}  // namespace

TEST(VaeFrameBatches, MatchDiffusersRule) {
  using P = std::vector<std::pair<int64_t, int64_t>>;
  EXPECT_EQ(CogVideoXVae::frame_batches(9, 8), (P{{0, 9}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(17, 8), (P{{0, 9}, {9, 17}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(49, 8), (P{{0, 9}, {9, 17}, {17, 25}, {25, 33}, {33, 41}, {41, 49}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(1, 8), (P{{0, 1}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(3, 2), (P{{0, 3}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(5, 2), (P{{0, 3}, {3, 5}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(13, 2), (P{{0, 3}, {3, 5}, {5, 7}, {7, 9}, {9, 11}, {11, 13}}));
  EXPECT_EQ(CogVideoXVae::frame_batches(16, 8), (P{{0, 8}, {8, 16}}));
}

TEST(VaeTilePlan, MatchesDiffusersArithmetic) {
  dvs::models::VaeConfig cfg;
  cfg.block_out_channels = {128, 256, 256, 512};
  const dvs::models::VaeTiling real{};  // 480x720 config: 240x360 tiles, overlap 1/6, 1/5
  auto e = dvs::models::TilePlan::for_encode(cfg, real);
  EXPECT_EQ(e.tile_in_h, 240);
  EXPECT_EQ(e.tile_in_w, 360);
  EXPECT_EQ(e.stride_h, 200);
  EXPECT_EQ(e.stride_w, 288);
  EXPECT_EQ(e.blend_h, 5);
  EXPECT_EQ(e.blend_w, 9);
  EXPECT_EQ(e.limit_h, 25);
  EXPECT_EQ(e.limit_w, 36);
  auto d = dvs::models::TilePlan::for_decode(cfg, real);
  EXPECT_EQ(d.tile_in_h, 30);
  EXPECT_EQ(d.tile_in_w, 45);
  EXPECT_EQ(d.stride_h, 25);
  EXPECT_EQ(d.stride_w, 36);
  EXPECT_EQ(d.blend_h, 40);
  EXPECT_EQ(d.blend_w, 72);
  EXPECT_EQ(d.limit_h, 200);
  EXPECT_EQ(d.limit_w, 288);
}

// Working-set plan of the real CogVideoX-5B-I2V VAE (its config values) at 49 x 480 x 720, whole frame and
// with diffusers' default 240 x 360 tiles: printed for the memory plan; a dry run, no device work.
TEST(VaeMemoryPlan, Real5BSizes) {
  const nlohmann::json real = dvs::pipeline::builtin_plan_model("cogvideox-5b-i2v").vae;
  const double gib = 1024.0 * 1024.0 * 1024.0;
  const uint64_t enc = CogVideoXVae::encode_working_bytes(real, {1, 3, 49, 480, 720});
  const uint64_t dec = CogVideoXVae::decode_working_bytes(real, {1, 16, 13, 60, 90});
  const uint64_t enc_tile = CogVideoXVae::encode_working_bytes(real, {1, 3, 49, 240, 360});
  const uint64_t dec_tile = CogVideoXVae::decode_working_bytes(real, {1, 16, 13, 30, 45});
  std::printf("[ plan   ] real VAE working set: encode 49x480x720 %.2f GiB (tile 240x360: %.2f GiB), decode 13x60x90 "
              "%.2f GiB (tile 30x45: %.2f GiB)\n",
              enc / gib, enc_tile / gib, dec / gib, dec_tile / gib);
  EXPECT_GT(enc, enc_tile);
  EXPECT_GT(dec, dec_tile);
}

TEST_F(VaeGolden, Encode) {
  const Tol tol = tolerance_of(pack_case("vae_encode")["tolerance"]);
  const Tensor video = up(load("vae/video.npy"));
  auto t0 = std::chrono::steady_clock::now();
  const auto post = vae().encode(video);
  std::printf("[ golden ] vae encode %s: %.3f s\n", dvs::shape_str(video.shape()).c_str(), seconds_since(t0));
  expect_close("vae_encode moments", dl(post.moments), "vae/encode_moments.npy", tol);
  expect_close("vae_encode mean", dl(post.mean), "vae/encode_mean.npy", tol);
  expect_close("vae_encode std", dl(post.std), "vae/encode_std.npy", tol);
  Tensor scaled = Tensor::empty(ctx(), post.mean.shape(), dvs::DType::f32);
  dvs::ops::run_now(ctx(), [&](dvs::vk::Recorder& rec) { vae().to_diffusion_latent(rec, post.mean, scaled); });
  expect_close("vae_encode scaled latent", dl(scaled), "vae/encode_scaled_latent.npy", tol);
}

TEST_F(VaeGolden, Decode) {
  const Tol tol = tolerance_of(pack_case("vae_decode")["tolerance"]);
  const Tensor z = up(divided(load("vae/encode_scaled_latent.npy"), scaling()));
  auto t0 = std::chrono::steady_clock::now();
  const Tensor frames = vae().decode(z);
  std::printf("[ golden ] vae decode %s: %.3f s\n", dvs::shape_str(z.shape()).c_str(), seconds_since(t0));
  expect_close("vae_decode frames", dl(frames), "vae/decode_frames.npy", tol);
}

// Tiling off (the tile is at least the input): encode_tiled / decode_tiled must give the untiled result.
TEST_F(VaeGolden, TilingDisabledExplicit) {
  const auto& tc = pack_case("vae_tiling_disabled_explicit")["tolerance"];
  const HostTensor video = load("vae/video.npy");
  dvs::models::VaeTiling off;
  off.tile_sample_min_height = video.shape[3];
  off.tile_sample_min_width = video.shape[4];
  const auto post = vae().encode_tiled(up(video), off);
  expect_close("vae_tiling_disabled mean", dl(post.mean), "vae/encode_mean.npy", tolerance_of(tc["encode"]));
  const Tensor z = up(divided(load("vae/encode_scaled_latent.npy"), scaling()));
  expect_close("vae_tiling_disabled decode", dl(vae().decode_tiled(z, off)), "vae/decode_frames.npy",
               tolerance_of(tc["decode"]));
}

TEST_F(VaeGolden, FrameBatching17) {
  const auto& tc = pack_case("vae_frame_batching")["tolerance"];
  const Tensor video = up(load("vae/chunk17_video.npy"));
  auto t0 = std::chrono::steady_clock::now();
  const auto post = vae().encode(video);
  std::printf("[ golden ] vae encode %s: %.3f s\n", dvs::shape_str(video.shape()).c_str(), seconds_since(t0));
  expect_close("vae_frame_batching mean", dl(post.mean), "vae/chunk17_encode_mean.npy", tolerance_of(tc["encode"]));
  expect_close("vae_frame_batching std", dl(post.std), "vae/chunk17_encode_std.npy", tolerance_of(tc["encode"]));
  // The dry-run memory plan is exactly what the live call allocated.
  EXPECT_EQ(vae().last_working_bytes(), CogVideoXVae::encode_working_bytes(vae().weights().config(), video.shape()));
  // Decode the golden mean (not ours) so the decoder is judged on its own.
  const Tensor z = up(load("vae/chunk17_encode_mean.npy"));
  t0 = std::chrono::steady_clock::now();
  const Tensor frames = vae().decode(z);
  std::printf("[ golden ] vae decode %s: %.3f s\n", dvs::shape_str(z.shape()).c_str(), seconds_since(t0));
  expect_close("vae_frame_batching decode", dl(frames), "vae/chunk17_decode_frames.npy", tolerance_of(tc["decode"]));
  EXPECT_EQ(vae().last_working_bytes(), CogVideoXVae::decode_working_bytes(vae().weights().config(), z.shape()));
}

TEST_F(VaeGolden, Tiled) {
  const auto& c = pack_case("vae_tiled");
  const auto& t = c["tiling"];
  dvs::models::VaeTiling tiling;
  tiling.tile_sample_min_height = t["tile_sample_min_height"].get<int64_t>();
  tiling.tile_sample_min_width = t["tile_sample_min_width"].get<int64_t>();
  tiling.tile_overlap_factor_height = t["tile_overlap_factor_height"].get<double>();
  tiling.tile_overlap_factor_width = t["tile_overlap_factor_width"].get<double>();
  const Tensor video = up(load("vae/video.npy"));
  auto t0 = std::chrono::steady_clock::now();
  const auto post = vae().encode_tiled(video, tiling);
  std::printf("[ golden ] vae tiled encode: %.3f s\n", seconds_since(t0));
  expect_close("vae_tiled mean", dl(post.mean), "vae/tiled_encode_mean.npy", tolerance_of(c["tolerance"]["encode"]));
  expect_close("vae_tiled std", dl(post.std), "vae/tiled_encode_std.npy", tolerance_of(c["tolerance"]["encode"]));
  const Tensor z = up(divided(load("vae/encode_scaled_latent.npy"), scaling()));
  t0 = std::chrono::steady_clock::now();
  const Tensor frames = vae().decode_tiled(z, tiling);
  std::printf("[ golden ] vae tiled decode: %.3f s\n", seconds_since(t0));
  expect_close("vae_tiled decode", dl(frames), "vae/tiled_decode_frames.npy", tolerance_of(c["tolerance"]["decode"]));
}


// Diagnostic of vae_frame_batching: with frame batching off (one batch for the whole clip) the result must
// move away from the golden by the recorded whole_clip_max_abs_diff, proving the batches matter and that the
// whole-clip path is the one diffusers would take (encode of the video; decode of the golden mean).
TEST_F(VaeGolden, WholeClipDiffersAsRecorded) {
  const auto& rec = pack_case("vae_frame_batching")["whole_clip_max_abs_diff"];
  auto max_diff = [](const HostTensor& a, const HostTensor& b) {
    const auto x = a.to_f32(), y = b.to_f32();
    double m = 0;
    for (size_t i = 0; i < x.size(); ++i) m = std::max(m, std::fabs(double(x[i]) - double(y[i])));
    return m;
  };
  CogVideoXVae& v = vae();
  const Tensor video = up(load("vae/chunk17_video.npy")), z = up(load("vae/chunk17_encode_mean.npy"));
  // The kernels' own error on the batched path (the golden's), measured first: the whole-clip difference may move
  // from the recorded one by at most the whole-clip path's own error (|max|w - g| - max|w* - g|| <= max|w - w*|,
  // w* diffusers' whole clip), which the batched path's error estimates (twice it: a margin for the estimate). Tiny
  // with fp32 kernels; with 16-bit ones far above the fp32 tolerance (the H200, 2026-11-29: the encode mean's
  // difference 7.3e-4 from the recorded one).
  const double enc_err = max_diff(dl(v.encode(video).mean), load("vae/chunk17_encode_mean.npy"));
  const double dec_err = max_diff(dl(v.decode(z)), load("vae/chunk17_decode_frames.npy"));
  v.sample_frames_batch = 1 << 20;
  v.latent_frames_batch = 1 << 20;
  const auto post = v.encode(video);
  const double enc = max_diff(dl(post.mean), load("vae/chunk17_encode_mean.npy"));
  const double dec = max_diff(dl(v.decode(z)), load("vae/chunk17_decode_frames.npy"));
  std::printf("[ golden ] whole clip: encode_mean diff %.6g (recorded %.6g), decode diff %.6g (recorded %.6g); the "
              "batched path's own error %.3g, %.3g\n",
              enc, rec["encode_mean"].get<double>(), dec, rec["decode"].get<double>(), enc_err, dec_err);
  EXPECT_NEAR(enc, rec["encode_mean"].get<double>(), 1e-3 * rec["encode_mean"].get<double>() + 1e-4 + 2 * enc_err);
  EXPECT_NEAR(dec, rec["decode"].get<double>(), 1e-3 * rec["decode"].get<double>() + 1e-3 + 2 * dec_err);
}

// Which decoded frames dvs keeps for an even latent count, against diffusers' decode of even-count latents
// (case vae_decode_even_latent: each latent decoded by AutoencoderKLCogVideoX itself to 4·Fl frames). First the
// whole decode must match; then decode_latent, what `dvs run` writes for a 4·Fl − 3 frame video, must return the
// golden's frames 3 .. 4·Fl − 1 (clamped to [−1, 1]). Keeping the first 4·Fl − 3 instead, or any other offset,
// fails here: the test also checks that the golden's frames differ by more than the tolerance under a shift.
TEST_F(VaeGolden, EvenLatentCountDecode) {
  const nlohmann::json* found = nullptr;
  for (const auto& c : pack_cases()["cases"])
    if (c["name"] == "vae_decode_even_latent") found = &c;
  if (!found) GTEST_SKIP() << pack() << "/cases.json has no case vae_decode_even_latent (our pack A has it)";
  const nlohmann::json& c = *found;
  const Tol tol = tolerance_of(c["tolerance"]);
  std::vector<std::string> inputs, outputs;
  for (const auto& f : c["files"]) (f["role"] == "input" ? inputs : outputs).push_back(f["file"].get<std::string>());
  ASSERT_EQ(inputs.size(), outputs.size());
  ASSERT_FALSE(inputs.empty());
  for (size_t i = 0; i < inputs.size(); ++i) {
    const HostTensor scaled = load(inputs[i]);  // [1, C, Fl, h, w], diffusion units
    const HostTensor want_all = load(outputs[i]);  // [1, 3, 4·Fl, H, W]
    const int64_t C = scaled.shape[1], Fl = scaled.shape[2], h = scaled.shape[3], w = scaled.shape[4];
    ASSERT_EQ(Fl % 2, 0) << inputs[i] << " is not an even latent count";
    ASSERT_EQ(want_all.shape[2], 4 * Fl) << outputs[i];
    expect_close(inputs[i] + " decode", dl(vae().decode(up(divided(scaled, scaling())))), outputs[i], tol);

    // decode_latent takes the diffusion latent as [Fl, C, h, w].
    std::vector<float> fc(size_t(scaled.numel()));
    const std::vector<float> cf = scaled.to_f32();
    for (int64_t f = 0; f < Fl; ++f)
      for (int64_t ch = 0; ch < C; ++ch)
        std::copy_n(cf.begin() + (ch * Fl + f) * h * w, h * w, fc.begin() + (f * C + ch) * h * w);
    const int frames = int(4 * Fl - 3);
    const HostTensor kept = dvs::decode_latent(ctx(), vae(), dvs::RunOptions{},
                                               up(HostTensor::from_f32({Fl, C, h, w}, fc)), scaling(), frames);
    const int64_t H = want_all.shape[3], W = want_all.shape[4], plane = H * W;
    ASSERT_EQ(kept.shape, (dvs::Shape{frames, 3, H, W}));
    // The frames of `all` (the golden or its bf16 run) from `first` on, clamped, as [frames, 3, H, W].
    auto frames_from = [&](const HostTensor& all, int64_t first) {
      const std::vector<float> g = all.to_f32();
      std::vector<float> v(size_t(frames * 3 * plane));
      for (int64_t f = 0; f < frames; ++f)
        for (int64_t ch = 0; ch < 3; ++ch)
          for (int64_t p = 0; p < plane; ++p)
            v[size_t((f * 3 + ch) * plane + p)] = std::clamp(g[size_t((ch * 4 * Fl + f + first) * plane + p)], -1.0f, 1.0f);
      return v;
    };
    auto golden_from = [&](int64_t first) { return HostTensor::from_f32(kept.shape, frames_from(want_all, first)); };
    const dvs::test::PackGolden pg = dvs::test::read_pack_golden(pack(), outputs[i]);
    std::optional<std::vector<float>> bf16_kept;
    if (pg.bf16) bf16_kept = frames_from(*pg.bf16, 3);
    dvs::test::expect_golden_values(inputs[i] + " kept frames", kept.shape, kept.to_f32(), kept.shape,
                                    frames_from(want_all, 3), bf16_kept, pg.bf16_path.string(), tol.atol, tol.rtol,
                                    dvs::test::kConvOps);
    // The golden tells the offsets apart: keeping the first frames (offset 0) would be far outside tolerance.
    const std::vector<float> last = golden_from(3).to_f32(), first = golden_from(0).to_f32();
    double shift = 0;
    for (size_t k = 0; k < last.size(); ++k) shift = std::max(shift, std::fabs(double(last[k]) - double(first[k])));
    EXPECT_GT(shift, 100 * (tol.atol + tol.rtol)) << "the golden cannot tell frame offsets 0 and 3 apart";
  }
}

// Timing on a mid size with the pack's weights (not part of the suite: run with
// --gtest_also_run_disabled_tests --gtest_filter='*VaeTiming*').
TEST_F(VaeGolden, DISABLED_VaeTimingMidSize) {
  const int64_t F = 17, H = 128, W = 192;
  std::vector<float> v(size_t(3 * F * H * W));
  for (size_t i = 0; i < v.size(); ++i) v[i] = float(std::sin(0.001 * double(i)));
  const Tensor video = up(HostTensor::from_f32({1, 3, F, H, W}, v));
  const bool profile = std::getenv("DVS_VAE_PROFILE") != nullptr;
  ctx().profiler().set_enabled(profile);
  auto t0 = std::chrono::steady_clock::now();
  const auto post = vae().encode(video);
  std::printf("[ timing ] encode %s: %.3f s\n", dvs::shape_str(video.shape()).c_str(), seconds_since(t0));
  t0 = std::chrono::steady_clock::now();
  const Tensor frames = vae().decode(post.mean);
  std::printf("[ timing ] decode %s: %.3f s\n", dvs::shape_str(post.mean.shape()).c_str(), seconds_since(t0));
  EXPECT_EQ(frames.dim(2), F);
  if (profile) std::printf("%s\n", ctx().profiler().report().c_str());
  ctx().profiler().set_enabled(false);
}
