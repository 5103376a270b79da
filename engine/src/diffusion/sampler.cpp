#include "diffusion/sampler.hpp"

#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "vk/context.hpp"

namespace dvs::diffusion {
namespace {

// The latent and model-output buffers one loop needs, reused by every step.
struct LoopBuffers {
  Tensor x[2], v, guided, pred_x0;
  LoopBuffers(vk::Context& ctx, const Tensor& start, bool cfg) {
    for (Tensor& t : x) t = Tensor::empty(ctx, start.shape(), DType::f32, "diffusion latent");
    Shape vs = start.shape();
    if (vs.size() == 5) vs.erase(vs.begin());
    vs.insert(vs.begin(), cfg ? 2 : 1);
    v = Tensor::empty(ctx, vs, DType::f32, "model output");
    guided = cfg ? Tensor::empty(ctx, start.shape(), DType::f32, "guided model output") : v.reshape(start.shape());
    pred_x0 = Tensor::empty(ctx, start.shape(), DType::f32, "x0 prediction");
  }
};

// Records v = model(x), the guidance combination and one linear step; returns the guided output.
const Tensor& record_step(vk::Recorder& rec, const Denoiser& model, const Guidance& g, LoopBuffers& b, const Tensor& x,
                          int model_t) {
  model(rec, x, model_t, b.v);
  if (g.enabled) {
    struct {
      uint32_t n;
      float scale;
    } push{uint32_t(x.numel()), float(g.scale)};
    ops::Grid grid = ops::grid_1d(x.numel(), 64);
    rec.dispatch(rec.context().pipelines().get("diffusion/cfg_combine"), {b.v.buffer(), b.guided.buffer()}, &push,
                 sizeof push, grid.x, grid.y, 1, "cfg_combine");
  }
  return b.guided;
}

void check_latent(const Tensor& x) {
  if (x.dtype() != DType::f32 || (x.rank() != 4 && !(x.rank() == 5 && x.dim(0) == 1)))
    throw Error("internal: diffusion latents are f32 [F,C,H,W], got " + x.describe());
}

}  // namespace

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
  LoopBuffers b(ctx, x0, guidance.enabled);
  vk::Recorder rec(ctx);
  int cur = 0;
  ops::run_now(ctx, [&](vk::Recorder& r) { r.copy(x0.buffer(), b.x[0].buffer(), x0.bytes()); });
  for (size_t i = 0; i < steps.size(); ++i) {
    if (cb.cancelled && cb.cancelled()) throw Cancelled();
    const StepCoefficients& c = steps[i];
    rec.begin();
    const Tensor& v = record_step(rec, model, guidance, b, b.x[cur], c.model_t);
    ops::axpby(rec, float(c.next.x), b.x[cur], float(c.next.v), v, b.x[1 - cur]);
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
  if (plan.timesteps.empty()) throw Error("sampling: the plan has no steps (raise --strength or --steps)");
  LoopBuffers b(ctx, x_init, guidance.enabled);
  vk::Recorder rec(ctx);
  int cur = 0;
  ops::run_now(ctx, [&](vk::Recorder& r) { r.copy(x_init.buffer(), b.x[0].buffer(), x_init.bytes()); });
  for (size_t i = 0; i < plan.timesteps.size(); ++i) {
    if (cb.cancelled && cb.cancelled()) throw Cancelled();
    const int t = plan.timesteps[i];
    const StepCoefficients c = s.step(t, plan.num_inference_steps);
    rec.begin();
    const Tensor& v = record_step(rec, model, guidance, b, b.x[cur], c.model_t);
    ops::axpby(rec, float(c.pred_x0.x), b.x[cur], float(c.pred_x0.v), v, b.pred_x0);
    ops::axpby(rec, float(c.next.x), b.x[cur], float(c.next.v), v, b.x[1 - cur]);
    rec.submit();
    cur = 1 - cur;
    if (cb.latent) cb.latent(int(i), t, b.x[cur]);
    if (cb.progress) cb.progress(int(i) + 1, plan.num_steps(), t);
  }
  return {b.x[cur], b.pred_x0};
}

}  // namespace dvs::diffusion
