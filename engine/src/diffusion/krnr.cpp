#include "diffusion/krnr.hpp"

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_reduce.hpp"
#include "vk/context.hpp"
#include "io/option_names.hpp"

namespace dvs::diffusion {

LatentDims LatentDims::of(const Tensor& t) {
  const Shape& s = t.shape();
  if (s.size() == 4) return {s[0], s[1], s[2], s[3]};
  if (s.size() == 5 && s[0] == 1) return {s[1], s[2], s[3], s[4]};
  throw Error("internal: a latent must be [F,C,H,W] or [1,F,C,H,W], got " + t.describe());
}

static void expect_same(const char* op, const Tensor& a, const Tensor& b) {
  if (a.numel() != b.numel() || a.dtype() != DType::f32 || b.dtype() != DType::f32)
    throw Error(std::string("internal: ") + op + ": " + a.describe() + " and " + b.describe() + " must be f32 of one size");
}

void krnr_combine(vk::Recorder& rec, const Tensor& x0, const Tensor& eps, reference::RnrCoefficients c, const Tensor& out) {
  ops::axpby(rec, float(c.m), x0, float(c.n), eps, out);
}

AdainWorkspace::AdainWorkspace(vk::Context& ctx, const LatentDims& d)
    : mean_x(Tensor::empty(ctx, {d.channels}, DType::f32, "AdaIN statistics")),
      var_x(Tensor::empty(ctx, {d.channels}, DType::f32, "AdaIN statistics")),
      mean_s(Tensor::empty(ctx, {d.channels}, DType::f32, "AdaIN statistics")),
      var_s(Tensor::empty(ctx, {d.channels}, DType::f32, "AdaIN statistics")),
      scratch(Tensor::empty(ctx,
                            {ops::reduce_scratch_elems(ctx.caps(), ops::channel_segments(d.frames, d.channels,
                                                                                         d.height * d.width))},
                            DType::f32, "AdaIN scratch")) {}

void adain_per_channel(vk::Recorder& rec, const Tensor& content, const Tensor& style, const Tensor& out,
                       const AdainWorkspace& ws, float eps) {
  expect_same("adain_per_channel", content, style);
  expect_same("adain_per_channel", content, out);
  LatentDims d = LatentDims::of(content);
  const int64_t inner = d.height * d.width;
  ops::channel_mean_var(rec, content, d.frames, d.channels, inner, ws.mean_x, ws.var_x, ws.scratch);
  rec.barrier();  // the scratch is reused by the second reduction
  ops::channel_mean_var(rec, style, d.frames, d.channels, inner, ws.mean_s, ws.var_s, ws.scratch);
  struct {
    uint32_t n, channels, inner;
    float eps;
    uint32_t plane0;
  } push{uint32_t(content.numel()), uint32_t(d.channels), uint32_t(inner), eps, 0};
  const vk::Pipeline& pipe = rec.context().pipelines().get("diffusion/adain_apply");
  // Whole channel planes per dispatch, within one binding (one dispatch when the latent fits).
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t plane = uint64_t(inner) * 4;
  const int64_t planes = content.numel() / inner;
  const int64_t per = ops::rows_per_chunk(caps, "adain_apply", {ops::RowOperand{plane, 0}}, planes);
  if (per < planes) rec.context().note_split("adain");
  ops::for_each_chunk(planes, per, [&](int64_t p0, int64_t np) {
    auto part = [&](const Tensor& t) { return np == planes ? t.buffer() : t.buffer().sub(p0 * plane, np * plane); };
    push.n = uint32_t(np * inner);
    push.plane0 = uint32_t(p0);
    const ops::Grid g = ops::grid_1d(caps, np * inner, 64);
    rec.dispatch(pipe,
                 {part(content), ws.mean_x.buffer(), ws.var_x.buffer(), ws.mean_s.buffer(), ws.var_s.buffer(),
                  part(out)},
                 &push, sizeof push, g.x, g.y, 1, "adain_apply");
  });
}

void krnr_official_round(vk::Recorder& rec, const Tensor& x0, const Tensor& eps, const Tensor& mu, const Tensor& sigma,
                         reference::RnrCoefficients ck, reference::RnrCoefficients cd, const Tensor& out) {
  for (const Tensor* t : {&eps, &mu, &sigma, &out}) expect_same("krnr_official_round", x0, *t);
  struct {
    uint32_t n;
    float m_k, n_k, m_d, n_d;
  } push{uint32_t(x0.numel()), float(ck.m), float(ck.n), float(cd.m), float(cd.n)};
  // Element ranges within one binding (one dispatch when the latent fits).
  const vk::DeviceCaps& caps = rec.context().caps();
  const int64_t n = x0.numel();
  const vk::Pipeline& pipe = rec.context().pipelines().get("diffusion/krnr_official");
  const int64_t per = ops::rows_per_chunk(caps, "krnr_official", {ops::RowOperand{4, 0}}, n);
  if (per < n) rec.context().note_split("krnr");
  ops::for_each_chunk(n, per, [&](int64_t f, int64_t m) {
    auto part = [&](const Tensor& t) { return m == n ? t.buffer() : t.buffer().sub(f * 4, m * 4); };
    push.n = uint32_t(m);
    const ops::Grid g = ops::grid_1d(caps, m, 64);
    rec.dispatch(pipe, {part(x0), part(eps), part(mu), part(sigma), part(out)}, &push, sizeof push, g.x, g.y, 1,
                 "krnr_official");
  });
}

Tensor adaptive_krnr_paper(vk::Context& ctx, const Tensor& x0, const Tensor& eps_inv, double abar, double k, double delta) {
  if (!(k > 0) || !(delta > 0)) 
    throw Error("K-RNR: " + option_name("RunOptions::k") + " and " + option_name("RunOptions::delta") + " must be > 0");
  LatentDims d = LatentDims::of(x0);
  Tensor eps_k = Tensor::empty(ctx, x0.shape(), DType::f32, "K-RNR"), eps_d = Tensor::empty(ctx, x0.shape(), DType::f32, "K-RNR");
  AdainWorkspace ws(ctx, d);
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    krnr_combine(rec, x0, eps_inv, reference::krnr_closed_form(abar, k), eps_k);
    krnr_combine(rec, x0, eps_inv, reference::krnr_closed_form(abar, delta), eps_d);
    adain_per_channel(rec, eps_k, eps_d, eps_k, ws);
  });
  return eps_k;
}

Tensor adaptive_krnr_official(vk::Context& ctx, const Tensor& x0, const Tensor& eps_inv, const Tensor& mu,
                              const Tensor& sigma, double abar, int k, int delta, int rounds) {
  if (k < 1 || delta < 1 || rounds < 1) throw Error("K-RNR (official): k, delta and rounds must be ≥ 1");
  Tensor a = Tensor::empty(ctx, x0.shape(), DType::f32, "K-RNR"), b = Tensor::empty(ctx, x0.shape(), DType::f32, "K-RNR");
  const auto ck = reference::krnr_series(abar, k), cd = reference::krnr_series(abar, delta);
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    const Tensor* in = &eps_inv;
    for (int r = 0; r < rounds; ++r) {
      const Tensor& out = (r % 2 == 0) ? a : b;  // ping-pong: a round never writes its own input
      krnr_official_round(rec, x0, *in, mu, sigma, ck, cd, out);
      in = &out;
    }
  });
  return rounds % 2 == 1 ? a : b;
}

}  // namespace dvs::diffusion
