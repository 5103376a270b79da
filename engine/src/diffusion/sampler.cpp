#include "diffusion/sampler.hpp"

#include <cmath>
#include <numbers>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"
#include "io/option_names.hpp"

namespace dvs::diffusion {
namespace {

// The latent and model-output buffers one loop needs, reused by every step.
struct LoopBuffers {
  Tensor x[2], v, pred_x0;
  LoopBuffers(vk::Context& ctx, const Tensor& start, bool cfg) {
    for (Tensor& t : x) t = Tensor::empty(ctx, start.shape(), DType::f32, "diffusion latent");
    Shape vs = start.shape();
    if (vs.size() == 5) vs.erase(vs.begin());
    vs.insert(vs.begin(), cfg ? 2 : 1);
    v = Tensor::empty(ctx, vs, DType::f32, "model output");
    pred_x0 = Tensor::empty(ctx, start.shape(), DType::f32, "x0 prediction");
  }
};

// Records v = model(x), then the guidance combination and the step's linear maps as one dispatch
// (shaders/diffusion/guided_step.comp): x_out = c.next(x, ĝ) and, when `with_pred`, pred_x0 = c.pred_x0(x, ĝ).
// `dynamic_scale` is the scale inside the positions for GuidanceMode::dynamic.
void record_step(vk::Recorder& rec, const Denoiser& model, const Guidance& g, LoopBuffers& b, const Tensor& x,
                 const Tensor& x_out, const StepCoefficients& c, bool with_pred, double dynamic_scale = 0) {
  model(rec, x, c.model_t, b.v);
  const bool dynamic = g.enabled && g.mode == GuidanceMode::dynamic;
  struct {
    uint32_t n, flags;
    float scale, dynamic_scale;
    float px, pv, nx, nv;
    uint32_t v1_off;
  } push{uint32_t(x.numel()),
         (g.enabled ? 1u : 0u) | (dynamic ? 2u : 0u) | (with_pred ? 4u : 0u),
         float(dynamic ? g.preservation_scale : g.scale),
         float(dynamic_scale),
         float(c.pred_x0.x),
         float(c.pred_x0.v),
         float(c.next.x),
         float(c.next.v),
         uint32_t(x.numel())};
  const vk::Pipeline& pipe = rec.context().pipelines().get("diffusion/guided_step");
  const vk::DeviceCaps& caps = rec.context().caps();
  const int64_t n = x.numel();
  if (b.v.bytes() <= ops::binding_capacity(caps, 0)) {
    const ops::Grid grid = ops::grid_1d(caps, n, 64);
    rec.dispatch(pipe,
                 {b.v.buffer(), x.buffer(), dynamic ? g.positions.buffer() : b.v.buffer(), x_out.buffer(),
                  b.pred_x0.buffer(), b.v.buffer()},
                 &push, sizeof push, grid.x, grid.y, 1, "guided_step");
    return;
  }
  rec.context().note_split("guided step");
  // Larger than one binding: element ranges of every tensor; v's second row (at element n, maybe unaligned)
  // bound from the aligned element at or before the range, the rest as v1_off.
  const int64_t align = int64_t(ops::binding_alignment(caps) / 4);
  int64_t per = ops::rows_per_chunk(caps, "guided_step", {ops::RowOperand{4, 0}}, n);
  if (uint64_t(per + align) * 4 > ops::binding_capacity(caps, 0)) per -= align;
  auto part = [](const Tensor& t, int64_t first, int64_t count) {
    return t.buffer().sub(VkDeviceSize(first) * 4, VkDeviceSize(count) * 4);
  };
  ops::for_each_chunk(n, per, [&](int64_t first, int64_t count) {
    const int64_t at = n + first, base = at / align * align;
    push.n = uint32_t(count);
    push.v1_off = uint32_t(at - base);
    const vk::BufferView v0 = part(b.v, first, count);
    const ops::Grid grid = ops::grid_1d(caps, count, 64);
    rec.dispatch(pipe,
                 {v0, part(x, first, count), dynamic ? part(g.positions, first, count) : v0, part(x_out, first, count),
                  part(b.pred_x0, first, count), g.enabled ? part(b.v, base, at - base + count) : v0},
                 &push, sizeof push, grid.x, grid.y, 1, "guided_step");
  });
}

void check_latent(const Tensor& x) {
  if (x.dtype() != DType::f32 || (x.rank() != 4 && !(x.rank() == 5 && x.dim(0) == 1)))
    throw Error("internal: diffusion latents are f32 [F,C,H,W], got " + x.describe());
}

void check_guidance(const Guidance& g, const Tensor& latent, bool sampling) {
  if (!g.enabled || g.mode == GuidanceMode::constant) return;
  if (!sampling) throw Error("internal: the inversion loop takes constant guidance only");
  if (!g.positions.defined() || g.positions.dtype() != DType::f32 || g.positions.numel() != latent.numel())
    throw Error("internal: dynamic guidance needs f32 positions of the latent's size " + latent.describe() + ", got " +
                (g.positions.defined() ? g.positions.describe() : std::string("none")));
}

}  // namespace

double dynamic_guidance_scale(double g, int t, int num_steps) {
  const double N = num_steps;
  return g + 2.0 - (1.0 + g * (1.0 - std::cos(std::numbers::pi * std::pow((N - double(t)) / N, 5.0))) / 2.0);
}

std::vector<StepCoefficients> inversion_steps_paper(const CogVideoXSchedule& s, int t0, int num_steps, bool model_at_target) {
  std::vector<StepCoefficients> out;
  int from = -1;
  for (int t : CogVideoXSchedule::paper_inversion_timesteps(t0, num_steps)) {
    out.push_back(s.inversion_step(from, t, model_at_target ? t : std::max(from, 0)));
    from = t;
  }
  return out;
}

std::vector<StepCoefficients> inversion_steps_official(const DDIMInverseSchedule& s, int num_steps, int up_to_t) {
  std::vector<StepCoefficients> out;
  for (int t : s.timesteps(num_steps))
    if (t <= up_to_t) out.push_back(s.step(t, num_steps));
  if (out.empty()) throw Error("inversion: no inversion step reaches t ≤ " + std::to_string(up_to_t));
  return out;
}

Tensor invert(vk::Context& ctx, const Tensor& x0, const std::vector<StepCoefficients>& steps, const Denoiser& model,
              const Guidance& guidance, const LoopCallbacks& cb) {
  check_latent(x0);
  check_guidance(guidance, x0, false);
  LoopBuffers b(ctx, x0, guidance.enabled);
  vk::Recorder rec(ctx);
  int cur = 0;
  ops::run_now(ctx, [&](vk::Recorder& r) { r.copy(x0.buffer(), b.x[0].buffer(), x0.bytes()); });
  for (size_t i = 0; i < steps.size(); ++i) {
    if (cb.cancelled && cb.cancelled()) throw Cancelled();
    const StepCoefficients& c = steps[i];
    rec.begin();
    record_step(rec, model, guidance, b, b.x[cur], b.x[1 - cur], c, false);
    rec.submit();
    cur = 1 - cur;
    if (cb.latent) cb.latent(int(i), c.to_t, b.x[cur]);
    if (cb.progress) cb.progress(int(i) + 1, int(steps.size()), c.to_t);
  }
  return b.x[cur];
}

SampleResult sample(vk::Context& ctx, const Tensor& x_init, const CogVideoXSchedule& s, const SamplingPlan& plan,
                    const Denoiser& model, const Guidance& guidance, const LoopCallbacks& cb) {
  check_latent(x_init);
  if (plan.timesteps.empty()) 
    throw Error("sampling: the plan has no steps (raise " + option_name("RunOptions::strength") + " or " +
                option_name("RunOptions::steps") + ")");
  check_guidance(guidance, x_init, true);
  LoopBuffers b(ctx, x_init, guidance.enabled);
  vk::Recorder rec(ctx);
  int cur = 0;
  ops::run_now(ctx, [&](vk::Recorder& r) { r.copy(x_init.buffer(), b.x[0].buffer(), x_init.bytes()); });
  for (size_t i = 0; i < plan.timesteps.size(); ++i) {
    if (cb.cancelled && cb.cancelled()) throw Cancelled();
    const int t = plan.timesteps[i];
    const StepCoefficients c = s.step(t, plan.num_inference_steps);
    rec.begin();
    record_step(rec, model, guidance, b, b.x[cur], b.x[1 - cur], c, true,
                dynamic_guidance_scale(guidance.scale, t, plan.num_steps()));
    rec.submit();
    cur = 1 - cur;
    if (cb.latent) cb.latent(int(i), t, b.x[cur]);
    if (cb.progress) cb.progress(int(i) + 1, plan.num_steps(), t);
  }
  return {b.x[cur], b.pred_x0};
}

}  // namespace dvs::diffusion
