// Norm, positional and reduction ops as memory-bound kernels: GB/s of useful traffic (each input read once,
// each output written once) next to the device's shader copy bandwidth measured in the same run.
// Shapes are CogVideoX-5B-like, cut to stay under lavapipe's 128 MiB binding limit; --quick shrinks them.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "harness.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_norm.hpp"
#include "tensor/ops_position.hpp"
#include "tensor/ops_reduce.hpp"
#include "vk/memory.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"

namespace dvs::bench {
namespace {

constexpr int kRepeats = 4;  // dispatches per submission, so submit-and-wait overhead is amortised

Tensor random_tensor(vk::Context& ctx, Shape shape, float offset = 0.0f, DType dt = DType::f32) {
  std::mt19937 rng(7);
  std::normal_distribution<float> dist(offset, 1.0f);
  std::vector<float> v(size_t(shape_numel(shape)));
  for (float& x : v) x = dist(rng);
  HostTensor h = HostTensor::from_f32(shape, v);
  if (dt == DType::bf16) {
    HostTensor b(shape, DType::bf16);
    for (size_t i = 0; i < v.size(); ++i) b.as<uint16_t>()[i] = f32_to_bf16(v[i]);
    return Tensor::upload(ctx, b);
  }
  return Tensor::upload(ctx, h);
}

// Records `op` kRepeats times, times the submission, reports ms per op and GB/s for `bytes` per op.
// Each op also gets a ratio to a copy timed right before it: on a machine shared with other jobs the load
// changes within a run.
void measure(Bench& b, CopyRun& copy_run, const std::string& op, const std::string& shape, double bytes, const std::string& note,
             const std::function<void(vk::Recorder&)>& record) {
  vk::Recorder rec(b.ctx());
  rec.begin();
  for (int i = 0; i < kRepeats; ++i) record(rec);
  rec.end();
  const double copy = copy_run.gbps();
  double ms = Bench::time_ms([&] { rec.submit(); }) / kRepeats;
  const double gbps = bytes / (ms * 1e6);
  char ratio[64];
  std::snprintf(ratio, sizeof ratio, "%.2fx adjacent copy (%.2f GB/s)", gbps / copy, copy);
  b.report({op, shape, ms, 0, gbps, note.empty() ? std::string(ratio) : note + "; " + ratio});
}

void norms(Bench& b) {
  vk::Context& ctx = b.ctx();
  CopyRun copy(ctx);  // lives within the group: Vulkan objects must go before the context
  const int64_t rows = b.quick() ? 1024 : 4096, D = 3072;
  {
    // CogVideoXLayerNormZero on [text 226; video] rows with the [B, 6D] modulation table.
    Tensor x = random_tensor(ctx, {1, rows, D}, 0.5f), y = Tensor::empty(ctx, {1, rows, D}, DType::f32);
    Tensor w = random_tensor(ctx, {D}, 1.0f, DType::bf16), bias = random_tensor(ctx, {D}, 0.0f, DType::bf16);
    ops::Modulation mod;
    mod.table = random_tensor(ctx, {1, 6 * D});
    mod.seq_len = rows;
    mod.split = 226;
    mod.shift_col[0] = 3 * D, mod.scale_col[0] = 4 * D, mod.shift_col[1] = 0, mod.scale_col[1] = D;
    const std::string shape = std::to_string(rows) + "x" + std::to_string(D);
    const double bytes = 2.0 * double(x.bytes());
    measure(b, copy, "layernorm_affine_bf16", shape, bytes, "", [&](vk::Recorder& r) { ops::layernorm(r, x, y, w, bias, 1e-5f); });
    {
      ops::ScopedTuningOverride mapping("norm_row_per_invocation=off");
      measure(b, copy, "layernorm_affine_bf16_wg", shape, bytes, "workgroup per row (GPU mapping)",
              [&](vk::Recorder& r) { ops::layernorm(r, x, y, w, bias, 1e-5f); });
    }
    {
      ops::ScopedTuningOverride mapping("norm_row_per_invocation=on");
      measure(b, copy, "layernorm_affine_bf16_inv", shape, bytes, "invocation per row (CPU mapping)",
              [&](vk::Recorder& r) { ops::layernorm(r, x, y, w, bias, 1e-5f); });
    }
    measure(b, copy, "layernorm_zero_modulated", shape, bytes, "adaLN, text/video split",
            [&](vk::Recorder& r) { ops::layernorm(r, x, y, w, bias, 1e-5f, &mod); });
    measure(b, copy, "layernorm_no_affine", shape, bytes, "", [&](vk::Recorder& r) { ops::layernorm(r, x, y, {}, {}, 1e-5f); });
    Tensor tw = random_tensor(ctx, {D}, 1.0f);
    measure(b, copy, "rmsnorm", shape, bytes, "", [&](vk::Recorder& r) { ops::rmsnorm(r, x, y, tw, 1e-6f); });
  }
  {
    // q of a fused QKV output [rows, 3*3072], 48 heads x 64, in place.
    const int64_t qrows = rows / 2;
    Tensor qkv = random_tensor(ctx, {qrows, 3 * D});
    Tensor w = random_tensor(ctx, {64}, 1.0f, DType::bf16), bias = random_tensor(ctx, {64}, 0.0f, DType::bf16);
    measure(b, copy, "head_layernorm_q", std::to_string(qrows) + "x48x64 in " + std::to_string(3 * D), 2.0 * qrows * D * 4.0,
            "in place, column slice", [&](vk::Recorder& r) { ops::head_layernorm(r, qkv, qkv, 48, 64, 0, w, bias); });
  }
  {
    // VAE GroupNorm + SiLU: 128 channels, 32 groups, frames x 120 x 180 (decoder at 1/4 resolution).
    const int64_t F = b.quick() ? 2 : 5;
    Shape s{1, 128, F, 120, 180};
    Tensor x = random_tensor(ctx, s, 2.0f), y = Tensor::empty(ctx, s, DType::f32);
    Tensor g = random_tensor(ctx, {128}, 1.0f, DType::bf16), be = random_tensor(ctx, {128}, 0.0f, DType::bf16);
    Tensor scratch = Tensor::empty(ctx, {ops::groupnorm_scratch_elems(s, 32)}, DType::f32);
    {
      // The statistics half alone (reduce_partials + reduce_merge), to split the cost.
      const int64_t n_groups = 32, len = x.numel() / n_groups;
      Tensor m = Tensor::empty(ctx, {n_groups}, DType::f32), v = Tensor::empty(ctx, {n_groups}, DType::f32);
      measure(b, copy, "groupnorm_stats_only", "1x128x" + std::to_string(F) + "x120x180 G32", double(x.bytes()), "bytes read",
              [&](vk::Recorder& r) {
                ops::reduce_segments(r, x, {n_groups, len, len, len, 0}, ops::ReduceMode::mean_var, m, v, scratch);
              });
    }
    measure(b, copy, "groupnorm", "1x128x" + std::to_string(F) + "x120x180 G32", 2.0 * double(x.bytes()),
            "stats pass reads x once more (3 dispatches)",
            [&](vk::Recorder& r) { ops::groupnorm(r, x, y, 32, g, be, 1e-6f, false, scratch); });
    measure(b, copy, "groupnorm_silu", "1x128x" + std::to_string(F) + "x120x180 G32", 2.0 * double(x.bytes()),
            "stats pass reads x once more (3 dispatches)",
            [&](vk::Recorder& r) { ops::groupnorm(r, x, y, 32, g, be, 1e-6f, true, scratch); });
  }
}

void positional(Bench& b) {
  vk::Context& ctx = b.ctx();
  CopyRun copy(ctx);
  {
    // RoPE on q and k (96 heads of 64 from column 0) of the video tokens of a fused QKV [rows, 9216].
    const int64_t text = 226, video = b.quick() ? 512 : 2048 - 226, L = text + video;
    Tensor qkv = random_tensor(ctx, {L, 9216});
    ops::RopeTables t = ops::cogvideox_rope_tables(64, 1, 1, video, 1, video);
    Tensor c = Tensor::upload(ctx, t.cos), s = Tensor::upload(ctx, t.sin);
    const double bytes = 2.0 * video * 6144 * 4.0 + 2.0 * double(c.bytes());
    measure(b, copy, "rope_qk", std::to_string(video) + "x96x64", bytes, "in place, q and k of fused QKV",
            [&](vk::Recorder& r) { ops::rope(r, qkv, qkv, 1, L, text, 96, 64, 0, c, s); });
  }
  {
    Tensor ts = random_tensor(ctx, {2}, 500.0f), e = Tensor::empty(ctx, {2, 3072}, DType::f32);
    measure(b, copy, "timestep_embedding", "2x3072", double(e.bytes()), "launch-bound",
            [&](vk::Recorder& r) { ops::timestep_embedding(r, ts, e); });
  }
  {
    const int64_t F = 13;
    auto host = [&] { return ops::cogvideox_rope_tables_for_video(480, 720, F, 8, 2, 60, 90, 64); };
    double ms = Bench::time_ms(host, 0.2);
    b.report({"rope_tables_host", "13x30x45x64", ms, 0, 0, "CPU, once per video size"});
  }
}

void reductions(Bench& b) {
  vk::Context& ctx = b.ctx();
  CopyRun copy(ctx);
  {
    // AdaIN statistics of a latent [F, C, H, W] = [13, 16, 60, 90] (real size) and a 16x larger one.
    for (int64_t scale : {1, 4}) {
      if (b.quick() && scale > 1) continue;
      const int64_t F = 13, C = 16, H = 60 * scale, W = 90 * scale;
      Tensor x = random_tensor(ctx, {F, C, H, W}, 3.0f);
      Tensor m = Tensor::empty(ctx, {C}, DType::f32), v = Tensor::empty(ctx, {C}, DType::f32);
      Tensor scratch = Tensor::empty(ctx, {ops::reduce_scratch_elems(C, F * H * W)}, DType::f32);
      measure(b, copy, "channel_mean_var", "13x16x" + std::to_string(H) + "x" + std::to_string(W), double(x.bytes()),
              "bytes read", [&](vk::Recorder& r) { ops::channel_mean_var(r, x, F, C, H * W, m, v, scratch); });
    }
  }
  {
    const int64_t n = b.quick() ? (1 << 22) : (1 << 24);
    Tensor x = random_tensor(ctx, {n});
    Tensor out = Tensor::empty(ctx, {1}, DType::f32);
    Tensor scratch = Tensor::empty(ctx, {ops::reduce_scratch_elems(1, n)}, DType::f32);
    measure(b, copy, "sum_all", std::to_string(n), double(x.bytes()), "bytes read",
            [&](vk::Recorder& r) { ops::sum_all(r, x, out, scratch); });
    measure(b, copy, "max_all", std::to_string(n), double(x.bytes()), "bytes read",
            [&](vk::Recorder& r) { ops::max_all(r, x, out, scratch); });
  }
}

Registration reg_norm("norm", 10, norms);
Registration reg_position("position", 10, positional);
Registration reg_reduce("reduce", 10, reductions);

}  // namespace
}  // namespace dvs::bench
