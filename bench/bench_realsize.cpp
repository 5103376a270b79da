// dvs-bench --filter realsize: the real CogVideoX-5B-I2V configuration with random bf16 weights generated on
// the device (no download, nothing on disk): every real width, head count, token count and resolution, fewer
// repeated layers (2 T5 layers, 1 transformer block, the full VAE). Calls: T5 on 2 prompts x 226 tokens; the
// transformer at batch 2 and batch 1 on 226 + 17,550 tokens; the VAE at 480x720, untiled and with 240x360
// tiles: encode of one frame (the image-conditioning call) and decode of one latent frame. Each output is
// checked against the CPU references (realsize_reference.hpp); each call prints its time, its measured device
// memory next to `dvs plan`'s figure and its largest binding next to the device limit, and the group ends with
// one JSON line per call. DVS_REALSIZE_SCALE=small runs the same calls at few tokens / pixels (same widths).
//
// Tolerance: max|device - reference| <= 1e-3 · max|reference| per call. Both sides compute in fp32 from the
// same bf16 weights; what differs is summation order (dot products up to 13,824 terms, softmax over up to
// 17,776 keys, GroupNorm over 44M values), whose rounding stays orders of magnitude below that. Where the call's
// GEMMs or convolutions run on tensor cores (the transformer under a coopmat linear family, the VAE under a coopmat
// conv family) their operands are fp16 (2^-11 relative each) and 1e-2 · max|reference| (kTensorCoreTolerance): on
// Mesa 26.1's tensor-core lavapipe at DVS_REALSIZE_SCALE=small (2026-11-30) the VAE calls came to 0.7-0.9e-3, the
// transformer's to 0.3e-3 (a reference rounding the convolutions' operands to fp16 as well did not come closer:
// after a few layers the two sides' fp16 roundings differ anyway), while a wrong index or tap errs by O(1).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "harness.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "pipeline/memory_plan.hpp"
#include "spec/model_schema.hpp"
#include "realsize_model.hpp"
#include "realsize_reference.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_random.hpp"

namespace dvs::bench {
namespace {

using namespace realsize;
using Clock = std::chrono::steady_clock;
using pipeline::StageMemory;

constexpr double kTolerance = 1e-3;             // relative to max|reference|
constexpr double kTensorCoreTolerance = 1e-2;  // the same, for calls with fp16 tensor-core operands (see above)

struct CallResult {
  std::string op;
  double seconds = 0, max_abs_err = 0, tolerance = 0;
  uint64_t peak_bytes = 0, plan_bytes = 0, max_binding_bytes = 0, limit_binding_bytes = 0;
  bool peak_exact = true;
  std::string skipped;  // why the call was not run (the plan refuses it under the limits in force)
  nlohmann::json extra;  // weights lines: where they live, host bytes, uploads
};

// Progress lines: the full proof runs for tens of minutes.
struct Progress {
  Clock::time_point start = Clock::now();
  void operator()(const std::string& what) const {
    std::printf("[realsize %7.1fs] %s\n", std::chrono::duration<double>(Clock::now() - start).count(), what.c_str());
    std::fflush(stdout);
  }
};

// Restarts the allocator's peak where the allocator can (Allocator::reset_peak); false where it cannot.
template <class A>
bool reset_peak(A& a) {
  if constexpr (requires { a.reset_peak(); }) {
    a.reset_peak();
    return true;
  } else {
    return false;
  }
}

// One device call: wall time, device memory above what was allocated before it, the largest binding.
// peak_bytes = peak in use during the call - in use before it. Without Allocator::reset_peak the peak is
// since start: when the call did not raise it, the growth of the reserved blocks is reported instead (a lower
// bound, flagged).
struct Meter {
  vk::Context& ctx;
  Clock::time_point t0;
  uint64_t in_use0, peak0, reserved0;
  bool reset;
  explicit Meter(vk::Context& c) : ctx(c) {
    ctx.reset_largest_binding();
    reset = reset_peak(ctx.allocator());
    const auto& s = ctx.allocator().stats();
    in_use0 = s.bytes_in_use;
    peak0 = s.peak_bytes_in_use;
    reserved0 = s.bytes_reserved;
    t0 = Clock::now();
  }
  void finish(CallResult& r) const {
    r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    const auto& s = ctx.allocator().stats();
    if (reset || s.peak_bytes_in_use > peak0) r.peak_bytes = s.peak_bytes_in_use - in_use0;
    else {
      r.peak_bytes = s.bytes_reserved > reserved0 ? s.bytes_reserved - reserved0 : 0;
      r.peak_exact = false;
    }
    r.max_binding_bytes = ctx.largest_binding();
    r.limit_binding_bytes = ctx.caps().max_storage_buffer_range;
  }
};

// Compares device values with the reference; fills max_abs_err / tolerance (kTensorCoreTolerance where `f16_operands`).
void compare(CallResult& r, const std::vector<float>& dev, const std::vector<float>& ref, bool f16_operands = false) {
  if (dev.size() != ref.size())
    throw Error("realsize " + r.op + ": " + std::to_string(dev.size()) + " device values vs " +
                std::to_string(ref.size()) + " reference values");
  double err = 0, mx = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const double e = std::abs(double(dev[i]) - double(ref[i]));
    err = std::isnan(e) ? INFINITY : std::max(err, e);
    mx = std::max(mx, std::abs(double(ref[i])));
  }
  r.max_abs_err = err;
  r.tolerance = (f16_operands ? kTensorCoreTolerance : kTolerance) * mx;
}

// The measured peak against the plan to the byte (the JSON lines come only at the end of the run).
std::string against_plan(uint64_t peak, uint64_t plan) {
  if (peak == plan) return "= plan, " + std::to_string(peak) + " B";
  return "plan " + std::string(peak < plan ? "+" : "-") + std::to_string(peak < plan ? plan - peak : peak - plan) + " B";
}

void print_call(const CallResult& r) {
  std::printf("  %-28s %9.2f s  max|err| %.3g (tol %.3g, %s)  peak %s%s (plan %s; %s)  largest binding %s (limit %s)\n",
              r.op.c_str(), r.seconds, r.max_abs_err, r.tolerance, r.max_abs_err <= r.tolerance ? "ok" : "FAIL",
              vk::format_bytes(r.peak_bytes).c_str(), r.peak_exact ? "" : " (reserved growth)",
              vk::format_bytes(r.plan_bytes).c_str(), against_plan(r.peak_bytes, r.plan_bytes).c_str(),
              vk::format_bytes(r.max_binding_bytes).c_str(), vk::format_bytes(r.limit_binding_bytes).c_str());
  std::fflush(stdout);
}

std::string json_line(const CallResult& r) {
  nlohmann::json j = {{"op", r.op}, {"seconds", r.seconds}, {"max_abs_err", r.max_abs_err},
                      {"tolerance", r.tolerance}, {"peak_bytes", r.peak_bytes}, {"plan_bytes", r.plan_bytes},
                      {"max_binding_bytes", r.max_binding_bytes}, {"limit_binding_bytes", r.limit_binding_bytes}};
  if (!r.skipped.empty()) j["skipped"] = r.skipped;
  if (!r.extra.is_null()) j.update(r.extra);
  return j.dump();
}

// A component's weights on the device against the plan (pipeline/weight_stream_plan.hpp): resident, every tensor;
// streamed, the slots and the tensors outside the blocks (the blocks are in pinned host memory).
CallResult weights_result(const std::string& op, const models::ComponentWeights& w, const models::BlockStream* stream,
                          const pipeline::WeightStreamPlan& plan) {
  CallResult r;
  r.op = op;
  r.peak_bytes = w.bytes_on_device() + (stream ? uint64_t(stream->slots()) * stream->slot_bytes() : 0);
  r.plan_bytes = stream ? plan.device_bytes() : plan.resident_bytes + plan.host_bytes;
  r.extra = {{"weights", stream ? "stream" : "resident"}, {"host_bytes", stream ? stream->host_bytes() : 0},
             {"plan_host_bytes", stream ? plan.host_bytes : 0}, {"uploads", stream ? stream->uploads() : 0}};
  std::printf("  %-28s %s on the device (plan %s; %s)%s\n", op.c_str(), vk::format_bytes(r.peak_bytes).c_str(),
              vk::format_bytes(r.plan_bytes).c_str(), against_plan(r.peak_bytes, r.plan_bytes).c_str(),
              stream ? (", streamed: " + std::to_string(stream->slots()) + (stream->slots() == 1 ? " slot of " : " slots of ") +
                        vk::format_bytes(stream->slot_bytes()) +
                        ", host copy " + vk::format_bytes(stream->host_bytes()) + ", " + std::to_string(stream->uploads()) +
                        " block uploads")
                           .c_str()
                     : ", resident");
  std::fflush(stdout);
  return r;
}

// The plan's verdict on a VAE call under the limits in force: its largest tensor must fit one allocation, and its
// peak with what the device already holds (the VAE's weights, the call's input) the device memory budget, as the
// whole-run plan counts a phase (a run under that budget tiles instead). A call the plan refuses is recorded as
// skipped, with the reason (true), instead of run.
bool refused_by_plan(vk::Context& ctx, const StageMemory& m, CallResult& r, const Progress& progress,
                     std::vector<CallResult>& out) {
  r.plan_bytes = m.total();
  const uint64_t budget = ctx.caps().memory_budget.bytes, held = ctx.allocator().stats().bytes_in_use;
  if (m.largest_bytes > ctx.caps().max_memory_allocation_size)
    r.skipped = m.largest_what + " (" + vk::format_bytes(m.largest_bytes) + ") exceeds maxMemoryAllocationSize " +
                vk::format_bytes(ctx.caps().max_memory_allocation_size);
  else if (budget && held + m.total() > budget)
    r.skipped = "its planned peak " + vk::format_bytes(m.total()) + " with the " + vk::format_bytes(held) +
                " the device already holds (weights, input) exceeds the device memory budget " + vk::format_bytes(budget);
  else {
    progress(r.op + ": the plan's peak " + vk::format_bytes(m.total()) + " (largest tensor " + m.largest_what + ", " +
             vk::format_bytes(m.largest_bytes) + ")");
    return false;
  }
  progress(r.op + " skipped: the plan refuses it here (" + r.skipped + ")");
  out.push_back(r);
  return true;
}

Tensor random_tensor(vk::Context& ctx, const Shape& shape, uint32_t stream, bool uniform) {
  Tensor t = Tensor::empty(ctx, shape, DType::f32, "realsize input");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    if (uniform) ops::random_uniform(rec, t, {7, stream, 0}, -1.0f, 1.0f);
    else ops::random_normal(rec, t, {7, stream, 0});
  });
  return t;
}

// DVS_REALSIZE_CALLS: a comma list of calls to run (t5, transformer, vae_encode, vae_encode_tiled, vae_decode,
// vae_decode_tiled; "transformer" is both batches); unset: all.
bool wanted(const std::string& call) {
  const char* env = std::getenv("DVS_REALSIZE_CALLS");
  if (!env || !*env) return true;
  const std::string list = std::string(",") + env + ",";
  return list.find("," + call + ",") != std::string::npos;
}

// Runs one call's body; a failure is printed and recorded as that call (max_abs_err inf, JSON null) and the
// run goes on: the other calls still prove something.
void guarded(std::vector<CallResult>& calls, const Progress& progress, const std::string& op,
             const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    progress(op + " FAILED: " + e.what());
    CallResult r;
    r.op = op;
    r.max_abs_err = INFINITY;
    calls.push_back(r);
  }
}

// ---- T5 ---------------------------------------------------------------------------------------------------------
// Returns the device's last_hidden_state on the host (the transformer's text input).
HostTensor run_t5(vk::Context& ctx, const Scale& sc, const Progress& progress, std::vector<CallResult>& out) {
  const nlohmann::json cfg = t5_config(sc);
  progress("T5: random weights (" + std::to_string(sc.t5_layers) + " layers, vocab " + std::to_string(sc.t5_vocab) + ")");
  models::ComponentWeights weights = random_weights(ctx, cfg, "random T5", 1);
  HostWeights hw(ctx, weights);
  hw.load_all();  // the reference's copies, before a streamed model takes its layers to host memory
  models::T5Encoder t5(ctx, std::move(weights), sc.weights);
  std::mt19937 rng(11);
  std::vector<std::vector<int32_t>> ids(size_t(sc.prompts), std::vector<int32_t>(size_t(sc.text_len)));
  for (auto& row : ids)
    for (auto& id : row) id = int32_t(rng() % uint32_t(sc.t5_vocab));
  CallResult r;
  r.op = "realsize_t5";
  r.plan_bytes =
      pipeline::plan_t5_stage(cfg, true, ctx.allocator().alignment(), sc.prompts, sc.text_len, &ctx.caps()).total();
  progress("T5: encode " + std::to_string(sc.prompts) + " x " + std::to_string(sc.text_len) + " tokens");
  HostTensor dev;
  {
    Meter m(ctx);
    Tensor y = t5.encode(ids);
    m.finish(r);
    dev = y.download(ctx);
  }
  progress("T5: CPU reference");
  compare(r, dev.to_f32(), t5_reference(hw, cfg, ids));
  print_call(r);
  out.push_back(r);
  out.push_back(weights_result(
      "realsize_t5_weights", t5.weights(), t5.stream(),
      pipeline::plan_weight_stream("text_encoder", t5_encoder_schema(cfg), "encoder.block.", {}, 2,
                                   "encoder.block.0.layer.0.SelfAttention.relative_attention_bias.weight",
                                   ctx.allocator().alignment(), 2)));
  return dev;
}

// ---- transformer --------------------------------------------------------------------------------------------------
void run_transformer(vk::Context& ctx, const Scale& sc, const Progress& progress, const HostTensor& text_host,
                     std::vector<CallResult>& out) {
  const nlohmann::json cfg = transformer_config(sc);
  progress("transformer: random weights (" + std::to_string(sc.transformer_layers) + " block)");
  models::ComponentWeights weights = random_weights(ctx, cfg, "random transformer", 2);
  HostWeights hw(ctx, weights);
  hw.load_all();  // the reference's copies, before a streamed model takes its blocks to host memory
  models::CogVideoXTransformer tr(ctx, std::move(weights), sc.weights);
  const int64_t B = 2, F = sc.latent_frames, H = sc.latent_height, W = sc.latent_width, L = sc.text_len;
  const int64_t C = cfg["in_channels"], p = cfg["patch_size"], Cout = cfg["out_channels"];
  const int64_t Hp = H / p, Wp = W / p, N = F * Hp * Wp;
  const Shape ls{B, F, C, H, W};
  const Tensor latent = random_tensor(ctx, ls, 1, false);
  const Tensor text = Tensor::upload(ctx, text_host, "realsize text");
  const std::vector<float> timesteps{999.0f, 500.0f};

  // Sampled video tokens per batch row: the first, the last, the rest spread pseudo-randomly.
  std::vector<TokenSample> samples;
  std::mt19937 rng(5);
  for (int64_t b = 0; b < B; ++b)
    for (int64_t i = 0; i < sc.sampled_tokens; ++i)
      samples.push_back({b, i == 0 ? 0 : i == 1 ? N - 1 : int64_t(rng() % uint64_t(N))});
  auto pick = [&](const HostTensor& y, int64_t batch_rows) {  // device values of the samples, (c, ky, kx) order
    const std::vector<float> v = y.to_f32();
    std::vector<float> picked;
    for (const TokenSample& s : samples) {
      if (s.b >= batch_rows) continue;
      const int64_t f = s.n / (Hp * Wp), yy = (s.n / Wp) % Hp, xx = s.n % Wp;
      for (int64_t c = 0; c < Cout; ++c)
        for (int64_t ky = 0; ky < p; ++ky)
          for (int64_t kx = 0; kx < p; ++kx)
            picked.push_back(v[size_t((((s.b * F + f) * Cout + c) * H + yy * p + ky) * W + xx * p + kx)]);
    }
    return picked;
  };

  HostTensor dev2, dev1;
  CallResult r2, r1;
  r2.op = "realsize_transformer_b2";
  r1.op = "realsize_transformer_b1";
  const uint64_t align = ctx.allocator().alignment();
  r2.plan_bytes = pipeline::plan_transformer_stage(cfg, align, 2, F, H, W, L, 2, &ctx.caps()).total();
  r1.plan_bytes = pipeline::plan_transformer_stage(cfg, align, 1, F, H, W, L, 2, &ctx.caps()).total();
  // One call measured from nothing: the model's arena and tables released, its inputs made inside the meter
  // (device copies of the shared inputs), as the plan counts them.
  auto call = [&](int64_t batch, CallResult& r, HostTensor& dev) {
    tr.release_call_memory();
    Meter m(ctx);
    const Tensor lat = Tensor::empty(ctx, {batch, F, C, H, W}, DType::f32, "realsize latent");
    const Tensor txt = Tensor::empty(ctx, {batch, L, text.dim(2)}, text.dtype(), "realsize text");
    ops::run_now(ctx, [&](vk::Recorder& rec) {
      rec.copy(latent.buffer(), lat.buffer(), lat.bytes());
      rec.copy(text.buffer(), txt.buffer(), txt.bytes());
    });
    Tensor y = tr.forward(lat, txt, std::span<const float>(timesteps.data(), size_t(batch)));
    m.finish(r);
    dev = y.download(ctx);
  };
  progress("transformer: batch 2 on " + std::to_string(L) + " + " + std::to_string(N) + " tokens");
  call(2, r2, dev2);
  progress("transformer: batch 1");
  call(1, r1, dev1);
  progress("transformer: CPU reference (" + std::to_string(samples.size()) + " sampled tokens)");
  const auto& rope = tr.rope_tables(F, H, W);
  const auto ref = transformer_reference(hw, cfg, latent.download(ctx).to_f32(), ls, text_host.to_f32(), L, timesteps,
                                         rope.first.download(ctx).to_f32(), rope.second.download(ctx).to_f32(), samples);
  std::vector<float> ref2, ref1;
  for (size_t i = 0; i < samples.size(); ++i) {
    ref2.insert(ref2.end(), ref[i].begin(), ref[i].end());
    if (samples[i].b == 0) ref1.insert(ref1.end(), ref[i].begin(), ref[i].end());  // batch 1 = row 0 alone
  }
  const bool f16_gemms = ops::device_tuning(ctx.caps()).linear == ops::KernelFamily::coopmat;
  compare(r2, pick(dev2, 2), ref2, f16_gemms);
  compare(r1, pick(dev1, 1), ref1, f16_gemms);
  print_call(r2);
  print_call(r1);
  out.push_back(r2);
  out.push_back(r1);
  out.push_back(weights_result("realsize_transformer_weights", tr.weights(), tr.stream(),
                               pipeline::plan_weight_stream("transformer", cogvideox_transformer_schema(cfg),
                                                            "transformer_blocks.", {}, 2, "", align, 2)));
}

// ---- VAE ------------------------------------------------------------------------------------------------------
void run_vae(vk::Context& ctx, const Scale& sc, const Progress& progress, std::vector<CallResult>& out) {
  const nlohmann::json cfg = vae_config(sc);
  progress("VAE: random weights");
  // Host copies of every weight first: the VAE packs its conv weights on the device when it is made
  // (ComponentWeights::packed_conv), which drops them as stored, and the references read the stored layout.
  models::ComponentWeights vae_weights = random_weights(ctx, cfg, "random VAE", 3);
  HostWeights hw(ctx, vae_weights);
  hw.load_all();
  models::CogVideoXVae vae(ctx, std::move(vae_weights));
  const int64_t H = sc.image_height, W = sc.image_width, r = vae.config().spatial_ratio();
  const int64_t Cl = vae.config().latent_channels, Fl = sc.decode_latent_frames;
  if (Fl != 1) throw Error("realsize: the VAE references cover one latent frame");
  models::VaeTiling tiling;
  tiling.tile_sample_min_height = sc.tile_height;
  tiling.tile_sample_min_width = sc.tile_width;
  const uint64_t align = ctx.allocator().alignment();
  const Shape vshape{1, vae.config().in_channels, 1, H, W}, zshape{1, Cl, Fl, H / r, W / r};
  const Tensor video = random_tensor(ctx, vshape, 2, true);
  const Tensor z = random_tensor(ctx, zshape, 3, false);
  const HostTensor video_host = video.download(ctx), z_host = z.download(ctx);
  const bool f16_convs = ops::device_tuning(ctx.caps()).conv == ops::KernelFamily::coopmat;  // the tolerance's
  const models::TilePlan enc_plan = models::TilePlan::for_encode(vae.config(), tiling);
  const models::TilePlan dec_plan = models::TilePlan::for_decode(vae.config(), tiling);

  auto encode_ref = [&](const HostTensor& v) {  // moments of one frame
    // Each downsampler pads (0, 1) and runs a 3x3 stride-2 conv: h -> floor(h / 2).
    int64_t hl = v.shape[3], wl = v.shape[4];
    for (int64_t s = 1; s < r; s *= 2) hl /= 2, wl /= 2;
    HostTensor m({1, 2 * Cl, 1, hl, wl}, DType::f32);
    const std::vector<float> y = vae_encode_reference(hw, cfg, v.to_f32(), v.shape[3], v.shape[4]);
    if (int64_t(y.size()) != m.numel()) throw Error("realsize: VAE encode reference size mismatch");
    std::copy(y.begin(), y.end(), m.as<float>());
    return m;
  };
  auto decode_ref = [&](const HostTensor& zt) {
    HostTensor f({1, vae.config().out_channels, 1, zt.shape[3] * r, zt.shape[4] * r}, DType::f32);
    const std::vector<float> y = vae_decode_reference(hw, cfg, zt.to_f32(), zt.shape[3], zt.shape[4]);
    std::copy(y.begin(), y.end(), f.as<float>());
    return f;
  };
  // Plans: the whole call; for a tiled call, the call on one tile (each tile is its own model call).
  const Shape enc_tile{1, vshape[1], 1, std::min(H, enc_plan.tile_in_h), std::min(W, enc_plan.tile_in_w)};
  const Shape dec_tile{1, Cl, Fl, std::min(zshape[3], dec_plan.tile_in_h), std::min(zshape[4], dec_plan.tile_in_w)};

  for (int tiled = 0; tiled < 2; ++tiled) {
    if (!wanted(tiled ? "vae_encode_tiled" : "vae_encode")) continue;
    guarded(out, progress, tiled ? "realsize_vae_encode_tiled" : "realsize_vae_encode", [&] {
      CallResult e;
      e.op = tiled ? "realsize_vae_encode_tiled" : "realsize_vae_encode";
      if (refused_by_plan(ctx, pipeline::plan_vae_encode_stage(cfg, align, tiled ? enc_tile : vshape), e, progress, out))
        return;
      progress("VAE: encode of one " + std::to_string(H) + "x" + std::to_string(W) + " frame" +
               (tiled ? " in " + std::to_string(sc.tile_height) + "x" + std::to_string(sc.tile_width) + " tiles" : ""));
      HostTensor dev;
      {
        Meter m(ctx);
        models::VaePosterior post = tiled ? vae.encode_tiled(video, tiling) : vae.encode(video);
        m.finish(e);
        dev = post.moments.download(ctx);
      }
      progress("VAE: encode CPU reference");
      const HostTensor ref = tiled ? models::run_tiled(enc_plan, video_host, encode_ref) : encode_ref(video_host);
      compare(e, dev.to_f32(), ref.to_f32(), f16_convs);
      print_call(e);
      out.push_back(e);
    });
  }
  for (int tiled = 0; tiled < 2; ++tiled) {
    if (!wanted(tiled ? "vae_decode_tiled" : "vae_decode")) continue;
    guarded(out, progress, tiled ? "realsize_vae_decode_tiled" : "realsize_vae_decode", [&] {
      CallResult d;
      d.op = tiled ? "realsize_vae_decode_tiled" : "realsize_vae_decode";
      if (refused_by_plan(ctx, pipeline::plan_vae_decode_stage(cfg, align, tiled ? dec_tile : zshape), d, progress, out))
        return;
      progress("VAE: decode of " + std::to_string(Fl) + " latent frame(s) " + std::to_string(zshape[3]) + "x" +
               std::to_string(zshape[4]) + (tiled ? " in tiles" : ""));
      HostTensor dev;
      {
        Meter m(ctx);
        Tensor y = tiled ? vae.decode_tiled(z, tiling) : vae.decode(z);
        m.finish(d);
        dev = y.download(ctx);
      }
      progress("VAE: decode CPU reference");
      const HostTensor ref = tiled ? models::run_tiled(dec_plan, z_host, decode_ref) : decode_ref(z_host);
      compare(d, dev.to_f32(), ref.to_f32(), f16_convs);
      print_call(d);
      out.push_back(d);
    });
  }
}

void realsize(Bench& b) {
  vk::Context& ctx = b.ctx();
  const Scale sc = scale_from_env();
  const Progress progress;
  const std::string limits = apply_profile(ctx, sc);
  std::printf("\n== realsize (%s scale): CogVideoX-5B-I2V widths, random bf16 weights made on the device; "
              "tolerance max|err| <= %.0e * max|ref| (%.0e for calls on tensor cores)\n   limits: %s; T5 and "
              "transformer weights %s\n",
              sc.name.c_str(), kTolerance, kTensorCoreTolerance, limits.c_str(), models::residency_name(sc.weights));
  std::vector<CallResult> calls;
  HostTensor text;
  if (wanted("t5")) guarded(calls, progress, "realsize_t5", [&] { text = run_t5(ctx, sc, progress, calls); });
  if (text.shape.empty() && wanted("transformer")) {  // no T5 output: random text embeddings
    text = HostTensor({2, sc.text_len, t5_config(sc)["d_model"].get<int64_t>()}, DType::f32);
    std::mt19937 rng(3);
    std::normal_distribution<float> nd;
    for (int64_t i = 0; i < text.numel(); ++i) text.as<float>()[i] = nd(rng);
  }
  if (wanted("transformer"))
    guarded(calls, progress, "realsize_transformer", [&] { run_transformer(ctx, sc, progress, text, calls); });
  if (wanted("vae_encode") || wanted("vae_encode_tiled") || wanted("vae_decode") || wanted("vae_decode_tiled"))
    guarded(calls, progress, "realsize_vae", [&] { run_vae(ctx, sc, progress, calls); });
  progress("done");
  std::printf("\n");
  for (const CallResult& r : calls) std::printf("%s\n", json_line(r).c_str());
  std::fflush(stdout);
  ctx.override_limits({});  // the profile's limits end with this group
}

Registration reg("realsize", 90, realsize);

}  // namespace
}  // namespace dvs::bench
