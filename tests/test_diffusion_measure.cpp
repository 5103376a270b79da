// Measurement, not a test (skipped unless DVS_MEASURE=1): how much of a guided sampling step is spent outside
// the transformer on the demo's tiny model (the demo clip's latent size, 3×4×12×16). The loop is the
// pipeline's: diffusion::sample() with pipeline/transformer_denoiser (x copied into each CFG row's frames next
// to the image half written once, the timestep upload, the transformer) and the fused guidance + DDIM step.
// Prints wall times per step of
//   model — the transformer alone on a prepared input, one submission per step;
//   full  — diffusion::sample() (constant and dynamic guidance);
// their difference as the glue share, and the GPU time of the glue dispatches (DVS_PROFILE timestamps).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <set>

#include "diffusion/sampler.hpp"
#include "pipeline/transformer_denoiser.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/random/tiny_model.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/random_latent.hpp"
#include "tensor/dispatch.hpp"
#include "vk/memory.hpp"
#include "vk/profiler.hpp"

namespace dvs {
using namespace diffusion;
namespace {

using Clock = std::chrono::steady_clock;

// The fastest repeat: other processes on the machine only ever add time.
double best(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

TEST(DiffusionMeasure, SamplingStepGlueShare) {
  if (!std::getenv("DVS_MEASURE")) GTEST_SKIP() << "set DVS_MEASURE=1 to measure";
  vk::Context& ctx = test::gpu();
  test::TempDir dir;
  models::TinyModelSpec spec;  // the demo's model (demo.cpp): 9 frames of 96×128
  spec.seed = 1;
  spec.sample_frames = 9;
  spec.sample_height = 12;
  spec.sample_width = 16;
  spec.text_len = 16;
  models::write_tiny_model(dir.path, spec);
  models::CogVideoXTransformer transformer(ctx, dir.path / "transformer");
  const Shape lat{3, 4, 12, 16};
  Tensor x_init = Tensor::upload(ctx, test::random_latent(lat, 1)), image = Tensor::upload(ctx, test::random_latent(lat, 2));
  Tensor text = Tensor::upload(ctx, test::random_latent({2, 16, 32}, 3));
  Tensor mask = Tensor::upload(ctx, test::random_latent(lat, 4));  // any values: only "≠ 0" matters
  TransformerDenoiser den(ctx, transformer, image, text, 2);

  CogVideoXSchedule s;
  const SamplingPlan plan = s.plan(20, 1.0);  // 20 steps
  const int steps = plan.num_steps(), repeats = 9;
  Tensor v = Tensor::empty(ctx, {2, 3, 4, 12, 16}, DType::f32);
  // The transformer call alone, on an input and an arena of its own (what the denoiser holds).
  Tensor input = Tensor::zeros(ctx, {2, 3, 8, 12, 16}, DType::f32), timesteps = Tensor::zeros(ctx, {2}, DType::f32);
  vk::Arena arena(ctx.allocator(), transformer.arena_bytes(2, 3, 12, 16, 16), "transformer activations");
  auto model_only = [&] {
    vk::Recorder rec(ctx);
    const auto t0 = Clock::now();
    for (size_t i = 0; i < plan.timesteps.size(); ++i) {
      rec.begin();
      arena.reset();
      transformer.record(rec, arena, input, text, timesteps, v);
      rec.submit();
    }
    return std::chrono::duration<double>(Clock::now() - t0).count() / steps;
  };
  auto full = [&](const Guidance& g) {
    const auto t0 = Clock::now();
    sample(ctx, x_init, s, plan, std::ref(den), g);
    return std::chrono::duration<double>(Clock::now() - t0).count() / steps;
  };
  Guidance constant{true, 6.0};
  Guidance dynamic = constant;
  dynamic.mode = GuidanceMode::dynamic;
  dynamic.positions = mask;
  dynamic.preservation_scale = 1.0;
  model_only();  // warm-up (pipeline compilation)
  full(constant);
  full(dynamic);
  std::vector<double> m, fc, fd;
  for (int r = 0; r < repeats; ++r) {  // interleaved, so drift in machine load hits all alike
    m.push_back(model_only());
    fc.push_back(full(constant));
    fd.push_back(full(dynamic));
  }
  const double tm = best(m), tc = best(fc), td = best(fd);
  std::printf("sampling step on the demo's tiny model (latent 3x4x12x16, CFG batch 2), fastest of %d runs of %d steps:\n",
              repeats, steps);
  std::printf("  transformer alone              %8.3f ms/step\n", tm * 1e3);
  std::printf("  sample(), constant CFG         %8.3f ms/step  glue %.3f ms = %.2f %%\n", tc * 1e3, (tc - tm) * 1e3,
              100 * (tc - tm) / tc);
  std::printf("  sample(), dynamic CFG          %8.3f ms/step  glue %.3f ms = %.2f %%\n", td * 1e3, (td - tm) * 1e3,
              100 * (td - tm) / td);

  // GPU time per op of each loop (timestamps around every dispatch).
  vk::Profiler& prof = ctx.profiler();
  const bool was = prof.enabled();
  const std::set<std::string> glue_ops = {"guided_step"};  // the input copies are transfers, not dispatches
  auto profile = [&](const char* what, const std::function<void()>& loop) {
    prof.clear();
    prof.set_enabled(true);
    loop();
    prof.set_enabled(false);
    double glue_ns = 0, all_ns = 0;
    uint64_t dispatches = 0, glue_dispatches = 0;
    for (const auto& [label, e] : prof.entries()) {
      all_ns += e.total_ns;
      dispatches += e.count;
      if (glue_ops.count(label)) glue_ns += e.total_ns, glue_dispatches += e.count;
    }
    std::printf("  GPU %-28s glue %6.1f us/step of %7.1f us/step = %.2f %%  (%.0f of %.0f dispatches per step)\n", what,
                glue_ns * 1e-3 / steps, all_ns * 1e-3 / steps, 100 * glue_ns / all_ns, double(glue_dispatches) / steps,
                double(dispatches) / steps);
  };
  profile("sample(), constant", [&] { full(constant); });
  profile("sample(), dynamic", [&] { full(dynamic); });
  prof.clear();
  prof.set_enabled(was);
}

}  // namespace
}  // namespace dvs
