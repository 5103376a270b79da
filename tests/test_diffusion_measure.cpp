// Measurement, not a test (skipped unless DVS_MEASURE=1): how much of a guided sampling step is spent outside
// the transformer on the demo's tiny model (the demo clip's latent size, 3×4×12×16). The denoiser is built
// as the pipeline builds it (pipeline/transformer_denoiser.cpp: concat(x, image latent) on channels, the row copy for the CFG
// batch, the timestep upload, the transformer), so the "glue" is that plus the sampler's guidance combine and
// scheduler step. Prints wall times per step of
//   model  — the transformer alone, one submission per step;
//   full   — diffusion::sample() with the pipeline's denoiser (constant and dynamic guidance);
// their difference as the glue share, and the GPU time of the glue ops (DVS_PROFILE timestamps). "prefilled" is
// a denoiser variant that writes the constant image half of the transformer input once and per step only
// copies x into each row's frames (no concat dispatches): what the pipeline's denoiser could do.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <set>

#include "diffusion/sampler.hpp"
#include "models/cogvideox_transformer.hpp"
#include "models/tiny_model.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "vk/memory.hpp"
#include "vk/profiler.hpp"

namespace dvs::diffusion {
namespace {

using Clock = std::chrono::steady_clock;

HostTensor random_host(Shape s, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, 1);
  HostTensor h(std::move(s), DType::f32);
  for (int64_t i = 0; i < h.numel(); ++i) h.as<float>()[i] = n(rng);
  return h;
}

// The pipeline's TransformerDenoiser (run_pipeline.cpp), restated so the measurement sees the same glue.
struct PipelineDenoiser {
  vk::Context& ctx;
  models::CogVideoXTransformer& model;
  Tensor image, text, input, timesteps;
  int batch;
  std::unique_ptr<vk::Arena> arena;
  bool glue = true;        // false: the transformer call only (input prepared once)
  bool prefilled = false;  // the image half written once; per step only x is copied into each row's frames

  PipelineDenoiser(vk::Context& c, models::CogVideoXTransformer& m, const Tensor& img, const Tensor& txt, int b)
      : ctx(c), model(m), image(img), text(txt), batch(b) {
    const Shape& s = img.shape();
    input = Tensor::empty(ctx, {batch, s[0], 2 * s[1], s[2], s[3]}, DType::f32, "transformer input");
    timesteps = Tensor::empty(ctx, {batch}, DType::f32, "timesteps");
    model.rope_tables(s[0], s[2], s[3]);
    model.positional_embedding(s[0], s[2], s[3], text.dim(1));
    arena = std::make_unique<vk::Arena>(ctx.allocator(), model.arena_bytes(batch, s[0], s[2], s[3], text.dim(1)),
                                        "transformer activations");
  }
  void operator()(vk::Recorder& rec, const Tensor& x, int t, const Tensor& v) {
    if (glue && prefilled) {
      const Shape& s = image.shape();
      const int64_t frame = s[1] * s[2] * s[3];
      const Tensor xs = x.reshape({s[0], frame}), rows = input.reshape({batch * s[0], 2 * frame});
      const std::vector<float> ts(static_cast<size_t>(batch), static_cast<float>(t));
      timesteps.write(ctx, HostTensor::from_f32({batch}, ts));
      for (int b = 0; b < batch; ++b)
        for (int64_t f = 0; f < s[0]; ++f)
          rec.copy(xs.rows(f, 1).buffer(), rows.rows(b * s[0] + f, 1).buffer(), uint64_t(frame) * 4);
    } else if (glue) {
      const Shape& s = image.shape();
      const std::vector<float> ts(static_cast<size_t>(batch), static_cast<float>(t));
      timesteps.write(ctx, HostTensor::from_f32({batch}, ts));
      Tensor row0 = input.rows(0, 1);
      ops::concat(rec, {x.reshape({1, s[0], s[1], s[2], s[3]}), image.reshape({1, s[0], s[1], s[2], s[3]})}, row0, 2);
      for (int b = 1; b < batch; ++b) rec.copy(row0.buffer(), input.rows(b, 1).buffer(), row0.bytes());
    }
    arena->reset();
    model.record(rec, *arena, input, text, timesteps, v);
  }
};

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
  Tensor x_init = Tensor::upload(ctx, random_host(lat, 1)), image = Tensor::upload(ctx, random_host(lat, 2));
  Tensor text = Tensor::upload(ctx, random_host({2, 16, 32}, 3));
  Tensor mask = Tensor::upload(ctx, random_host(lat, 4));  // any values: only "≠ 0" matters
  PipelineDenoiser den(ctx, transformer, image, text, 2);

  CogVideoXSchedule s;
  const SamplingPlan plan = s.plan(20, 1.0);  // 20 steps
  const int steps = plan.num_steps(), repeats = 9;
  Tensor v = Tensor::empty(ctx, {2, 3, 4, 12, 16}, DType::f32);
  auto model_only = [&] {
    den.glue = false;
    vk::Recorder rec(ctx);
    const auto t0 = Clock::now();
    for (int t : plan.timesteps) {
      rec.begin();
      den(rec, x_init, t, v);
      rec.submit();
    }
    den.glue = true;
    return std::chrono::duration<double>(Clock::now() - t0).count() / steps;
  };
  // The loop as it was before the fusion: the combine and the two linear maps as three dispatches (the
  // combine as an axpby: (1 − g)·u + g·c, the same traffic as the old cfg_combine shader).
  auto unfused = [&](double g) {
    Tensor xb[2] = {Tensor::empty(ctx, lat, DType::f32), Tensor::empty(ctx, lat, DType::f32)};
    Tensor guided = Tensor::empty(ctx, lat, DType::f32), pred = Tensor::empty(ctx, lat, DType::f32);
    ops::run_now(ctx, [&](vk::Recorder& r) { r.copy(x_init.buffer(), xb[0].buffer(), x_init.bytes()); });
    vk::Recorder rec(ctx);
    int cur = 0;
    const auto t0 = Clock::now();
    for (int t : plan.timesteps) {
      const StepCoefficients c = s.step(t, plan.num_inference_steps);
      rec.begin();
      den(rec, xb[cur], t, v);
      ops::axpby(rec, float(1 - g), v.rows(0, 1).reshape(lat), float(g), v.rows(1, 1).reshape(lat), guided);
      ops::axpby(rec, float(c.pred_x0.x), xb[cur], float(c.pred_x0.v), guided, pred);
      ops::axpby(rec, float(c.next.x), xb[cur], float(c.next.v), guided, xb[1 - cur]);
      rec.submit();
      cur = 1 - cur;
    }
    return std::chrono::duration<double>(Clock::now() - t0).count() / steps;
  };
  auto full = [&](const Guidance& g) {
    const auto t0 = Clock::now();
    sample(ctx, x_init, s, plan, std::ref(den), g);
    return std::chrono::duration<double>(Clock::now() - t0).count() / steps;
  };
  auto prefill = [&] {  // what the prefilled denoiser keeps from its construction: [x; image] per row
    const Shape& sh = lat;
    ops::run_now(ctx, [&](vk::Recorder& rec) {
      for (int b = 0; b < 2; ++b)
        ops::concat(rec, {x_init.reshape({1, sh[0], sh[1], sh[2], sh[3]}), image.reshape({1, sh[0], sh[1], sh[2], sh[3]})},
                    den.input.rows(b, 1), 2);
    });
  };
  auto full_prefilled = [&](const Guidance& g) {
    den.prefilled = true;
    const double r = full(g);
    den.prefilled = false;
    return r;
  };
  prefill();
  Guidance constant{true, 6.0};
  Guidance dynamic = constant;
  dynamic.mode = GuidanceMode::dynamic;
  dynamic.positions = mask;
  dynamic.preservation_scale = 1.0;
  model_only();  // warm-up (pipeline compilation)
  full(constant);
  full(dynamic);
  full_prefilled(constant);
  unfused(6.0);
  std::vector<double> m, fc, fd, fp, fu;
  for (int r = 0; r < repeats; ++r) {  // interleaved, so drift in machine load hits all alike
    m.push_back(model_only());
    fu.push_back(unfused(6.0));
    fc.push_back(full(constant));
    fd.push_back(full(dynamic));
    fp.push_back(full_prefilled(constant));
  }
  const double tm = best(m), tc = best(fc), td = best(fd), tp = best(fp), tu = best(fu);
  std::printf("sampling step on the demo's tiny model (latent 3x4x12x16, CFG batch 2), fastest of %d runs of %d steps:\n",
              repeats, steps);
  std::printf("  transformer alone              %8.3f ms/step\n", tm * 1e3);
  std::printf("  before fusion, constant CFG    %8.3f ms/step  glue %.3f ms = %.2f %%  (combine + 2 axpby)\n", tu * 1e3,
              (tu - tm) * 1e3, 100 * (tu - tm) / tu);
  std::printf("  sample(), constant CFG         %8.3f ms/step  glue %.3f ms = %.2f %%\n", tc * 1e3, (tc - tm) * 1e3,
              100 * (tc - tm) / tc);
  std::printf("  sample(), dynamic CFG          %8.3f ms/step  glue %.3f ms = %.2f %%\n", td * 1e3, (td - tm) * 1e3,
              100 * (td - tm) / td);
  std::printf("  sample(), constant, prefilled  %8.3f ms/step  glue %.3f ms = %.2f %%  (image half written once)\n",
              tp * 1e3, (tp - tm) * 1e3, 100 * (tp - tm) / tp);

  // GPU time per op of each loop (timestamps around every dispatch).
  vk::Profiler& prof = ctx.profiler();
  const bool was = prof.enabled();
  const std::set<std::string> glue_ops = {"concat", "axpby", "guided_step"};
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
  profile("before fusion, constant", [&] { unfused(6.0); });
  profile("sample(), constant", [&] { full(constant); });
  profile("sample(), dynamic", [&] { full(dynamic); });
  profile("sample(), constant, prefilled", [&] { full_prefilled(constant); });
  prof.clear();
  prof.set_enabled(was);
}

}  // namespace
}  // namespace dvs::diffusion
