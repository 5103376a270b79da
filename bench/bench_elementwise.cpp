// Elementwise, layout and random ops: GB/s (bytes read + written per call) next to the device's shader
// copy bandwidth measured in the same run. Tensors of ~64 MiB like the copy benchmark, one dispatch per
// submission (the submit-and-wait cost, ~0.1 ms, is included as it is in the copy figure).
// The machine is shared and its load drifts, so each op is also timed interleaved with the shader copy of
// 64 MiB (bench/copy, the harness's reference), taking the best of several alternating runs of each; the note
// gives that same-moment ratio ("vs copy now"), which is steadier than the ratio to the copy measured at start.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "harness.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_random.hpp"
#include "tensor/ops_resize.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"
#include "vk/transfer.hpp"

namespace dvs::bench {
namespace {

Tensor filled(vk::Context& ctx, const Shape& s, DType t = DType::f32) {
  Tensor x = Tensor::empty(ctx, s, t, "bench tensor");
  ctx.transfer().fill_zero(x.buffer());
  return x;
}

double once_ms(vk::Recorder& rec) {
  auto a = std::chrono::steady_clock::now();
  rec.submit();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count();
}

double cpu_ms_per_call(vk::Recorder& rec, int calls) {
  const double a = cpu_seconds();  // all threads, so lavapipe's workers are included
  for (int i = 0; i < calls; ++i) rec.submit();
  return (cpu_seconds() - a) * 1e3 / calls;
}

void measure(Bench& b, CopyRun& copy, const std::string& op, const std::string& shape, double bytes,
             const std::function<void(vk::Recorder&)>& record, const std::string& note = {}) {
  vk::Recorder rec(b.ctx());
  rec.begin();
  record(rec);
  rec.end();
  const double ms = Bench::time_ms([&] { rec.submit(); }, b.quick() ? 0.2 : 0.5);
  double best_op = 1e30, best_copy = 1e30;
  for (int i = 0; i < (b.quick() ? 3 : 6); ++i) {
    best_op = std::min(best_op, once_ms(rec));
    best_copy = std::min(best_copy, once_ms(copy.recorder));
  }
  std::string now;
  char buf[160];
  std::snprintf(buf, sizeof buf, "best %.2f GB/s = %.2fx copy now", bytes / (best_op * 1e6),
                (bytes / best_op) / (copy.bytes / best_copy));
  now = buf;
  if (b.ctx().caps().type == VK_PHYSICAL_DEVICE_TYPE_CPU) {
    const int calls = b.quick() ? 2 : 4;
    const double cpu_op = cpu_ms_per_call(rec, calls), cpu_copy = cpu_ms_per_call(copy.recorder, calls);
    std::snprintf(buf, sizeof buf, "; by CPU time %.2fx copy", (bytes / cpu_op) / (copy.bytes / cpu_copy));
    now += buf;
  }
  b.report({op, shape, ms, 0, bytes / (ms * 1e6), note.empty() ? std::string(now) : note + "; " + now});
}

void elementwise(Bench& b) {
  vk::Context& ctx = b.ctx();
  CopyRun copy(ctx);  // lives within the group: Vulkan objects must go before the context
  const int64_t n = b.quick() ? (4 << 20) : (16 << 20);  // f32 elements: 64 MiB, like the copy benchmark
  const double f = 4.0 * double(n);
  const std::string sn = std::to_string(n >> 20) + "M f32";
  Tensor x = filled(ctx, {n}), y = filled(ctx, {n}), z = filled(ctx, {n});
  measure(b, copy, "scale", sn, 2 * f, [&](vk::Recorder& r) { ops::scale(r, x, z, 0.7f, 0.1f); });
  measure(b, copy, "silu", sn, 2 * f, [&](vk::Recorder& r) { ops::silu(r, x, z); });
  measure(b, copy, "gelu_tanh", sn, 2 * f, [&](vk::Recorder& r) { ops::gelu_tanh(r, x, z); });
  measure(b, copy, "gelu_erf", sn, 2 * f, [&](vk::Recorder& r) { ops::gelu_erf(r, x, z); });
  measure(b, copy, "relu", sn, 2 * f, [&](vk::Recorder& r) { ops::relu(r, x, z); });
  measure(b, copy, "clamp", sn, 2 * f, [&](vk::Recorder& r) { ops::clamp(r, x, z, -1.0f, 1.0f); });
  measure(b, copy, "add", sn, 3 * f, [&](vk::Recorder& r) { ops::add(r, x, y, z); });
  {
    // The storage-buffer inputs the "gpu" tuning entry runs (eltwise_texel_inputs=off), beside the above.
    ops::ScopedTuningOverride storage("eltwise_texel_inputs=off");
    measure(b, copy, "silu_storage_inputs", sn, 2 * f, [&](vk::Recorder& r) { ops::silu(r, x, z); });
    measure(b, copy, "add_storage_inputs", sn, 3 * f, [&](vk::Recorder& r) { ops::add(r, x, y, z); });
  }
  Tensor one = filled(ctx, {1});
  measure(b, copy, "mul_scalar_tensor", sn, 2 * f, [&](vk::Recorder& r) { ops::mul(r, x, one, z); });
  measure(b, copy, "axpby_inplace", sn, 3 * f, [&](vk::Recorder& r) { ops::axpby(r, 0.9f, x, 0.1f, y, x); });
  // Broadcast second operands: a row vector [3072] (the transformer's modulation) and per-channel [C,1,1].
  const Shape rs = {n / 3072, 3072};
  Tensor rows_x = Tensor::on(x.buffer(), rs, DType::f32), rows_z = Tensor::on(z.buffer(), rs, DType::f32);
  Tensor vec = filled(ctx, {3072});
  measure(b, copy, "mul_rowvector", shape_str(rs), 2.0 * 4 * double(rows_x.numel()),
          [&](vk::Recorder& r) { ops::mul(r, rows_x, vec, rows_z); });
  const int64_t C = 16, inner = n / C / 13;
  Tensor chan_x = Tensor::on(x.buffer(), {13, C, inner}, DType::f32), chan_z = Tensor::on(z.buffer(), {13, C, inner}, DType::f32);
  Tensor cvec = filled(ctx, {C, 1});
  measure(b, copy, "add_perchannel", shape_str(chan_x.shape()), 2.0 * 4 * double(chan_x.numel()),
          [&](vk::Recorder& r) { ops::add(r, chan_x, cvec, chan_z); });
  Tensor cshift = filled(ctx, {C, 1});
  measure(b, copy, "scale_shift_perchannel", shape_str(chan_x.shape()), 2.0 * 4 * double(chan_x.numel()),
          [&](vk::Recorder& r) { ops::scale_shift(r, chan_x, cvec, cshift, chan_z); }, "AdaIN-style");
  Tensor rshift = filled(ctx, {3072});
  measure(b, copy, "scale_shift_rows", shape_str(rs), 2.0 * 4 * double(rows_x.numel()),
          [&](vk::Recorder& r) { ops::scale_shift(r, rows_x, vec, rshift, rows_z, 1.0f); }, "adaLN x(1+scale)+shift");
  Tensor odd_x = Tensor::on(x.buffer(), {n - 1}, DType::f32), odd_z = Tensor::on(z.buffer(), {n - 1}, DType::f32);
  measure(b, copy, "silu_odd_count", std::to_string(n - 1) + " f32", 2 * f, [&](vk::Recorder& r) { ops::silu(r, odd_x, odd_z); },
          "vec4 body + scalar tail");
  // Bilinear resize (align_corners, as the depth head): the VDA head's 2x upsample of 4 frames x 32 channels
  // and its output resize to 518x784; bytes = input read + output written.
  {
    const int64_t ih = b.quick() ? 64 : 140, iw = b.quick() ? 96 : 220;  // output within the 64 MiB buffers
    Tensor rin = Tensor::on(x.buffer(), {4, 32, ih, iw}, DType::f32);
    Tensor rout = Tensor::on(z.buffer(), {4, 32, ih * 2, iw * 2}, DType::f32);
    measure(b, copy, "resize_bilinear_2x", shape_str(rin.shape()) + "->" + std::to_string(ih * 2) + "x" + std::to_string(iw * 2),
            4.0 * double(rin.numel() + rout.numel()), [&](vk::Recorder& r) { ops::resize_bilinear(r, rin, rout, true); });
  }
  Tensor h = filled(ctx, {n}, DType::bf16);
  measure(b, copy, "cast_f32_bf16", sn, f + f / 2, [&](vk::Recorder& r) { ops::cast(r, x, h); });
  measure(b, copy, "cast_bf16_f32", sn, f + f / 2, [&](vk::Recorder& r) { ops::cast(r, h, z); });
  Tensor hf = Tensor::on(h.buffer(), {n}, DType::f16);
  measure(b, copy, "cast_f32_f16", sn, f + f / 2, [&](vk::Recorder& r) { ops::cast(r, x, hf); });
}

void layout(Bench& b) {
  vk::Context& ctx = b.ctx();
  CopyRun copy(ctx);  // lives within the group: Vulkan objects must go before the context
  const int64_t q = b.quick() ? 4 : 1;
  // Concat of two latents on channels ([B, F, C, H, W], the I2V input) at 8x the real latent area.
  Shape half = {1, 13, 16, 120 / q, 360};
  Tensor a = filled(ctx, half), c = filled(ctx, half), cat = filled(ctx, {1, 13, 32, 120 / q, 360});
  const double cb = 2.0 * 4 * double(cat.numel());
  measure(b, copy, "concat_channels", "2x" + shape_str(half), cb, [&](vk::Recorder& r) { ops::concat(r, {a, c}, cat, 2); });
  measure(b, copy, "split_channels", shape_str(cat.shape()), cb, [&](vk::Recorder& r) { ops::split(r, cat, {a, c}, 2); });
  Tensor perm_out = filled(ctx, {1, 32, 13, 120 / q, 360});
  measure(b, copy, "permute_BFCHW_BCFHW", shape_str(cat.shape()), cb,
          [&](vk::Recorder& r) { ops::permute(r, cat, perm_out, {0, 2, 1, 3, 4}); });
  const int64_t t = 2048 / q;
  Tensor sq = filled(ctx, {t, t}), sqt = filled(ctx, {t, t});
  measure(b, copy, "permute_transpose2d", shape_str(sq.shape()), 2.0 * 4 * double(sq.numel()),
          [&](vk::Recorder& r) { ops::permute(r, sq, sqt, {1, 0}); }, "worst case: scattered reads");
  const int64_t H = 120 / q, W = 360, Hp = H / 2, Wp = W / 2;
  Tensor tokens = filled(ctx, {1, 13 * Hp * Wp, 32 * 4});
  measure(b, copy, "patchify_p2", shape_str(cat.shape()), cb, [&](vk::Recorder& r) { ops::patchify(r, cat, tokens, 2); });
  measure(b, copy, "unpatchify_p2", shape_str(tokens.shape()), cb, [&](vk::Recorder& r) { ops::unpatchify(r, tokens, cat, 2); });
  // SLM-style element gather: m random indices into a latent-sized pool (rows of one element).
  const int64_t m = (4 << 20) / q;
  HostTensor idx({m}, DType::i32);
  uint32_t s = 1;
  for (int64_t i = 0; i < m; ++i) idx.as<int32_t>()[i] = int32_t((s = s * 1664525u + 1013904223u) % uint32_t(m));
  Tensor ti = Tensor::upload(ctx, idx), pool = filled(ctx, {m, 1}), g = filled(ctx, {m, 1});
  measure(b, copy, "gather_elements", std::to_string(m) + " idx", 3.0 * 4 * double(m),
          [&](vk::Recorder& r) { ops::gather_rows(r, pool, ti, g); }, "random indices");
  Tensor rows = filled(ctx, {m / 32, 32}), grows = filled(ctx, {m / 32, 32});
  Tensor ti_rows = Tensor::on(ti.buffer(), {m / 32}, DType::i32);
  HostTensor idx_rows({m / 32}, DType::i32);
  for (int64_t i = 0; i < m / 32; ++i) idx_rows.as<int32_t>()[i] = int32_t(idx.as<int32_t>()[i] % (m / 32));
  ti_rows.write(ctx, idx_rows);
  measure(b, copy, "gather_rows_32", std::to_string(m / 32) + "x32", 2.0 * 4 * double(m) + 4.0 * double(m / 32),
          [&](vk::Recorder& r) { ops::gather_rows(r, rows, ti_rows, grows); });
}

void random(Bench& b) {
  vk::Context& ctx = b.ctx();
  CopyRun copy(ctx);  // lives within the group: Vulkan objects must go before the context
  const int64_t n = b.quick() ? (4 << 20) : (16 << 20);
  const std::string sn = std::to_string(n >> 20) + "M";
  Tensor x = filled(ctx, {n}), i = filled(ctx, {n}, DType::i32);
  const double bytes = 4.0 * double(n);
  measure(b, copy, "random_uniform", sn + " f32", bytes, [&](vk::Recorder& r) { ops::random_uniform(r, x, {1, 0, 0}); },
          "bytes written");
  measure(b, copy, "random_normal", sn + " f32", bytes, [&](vk::Recorder& r) { ops::random_normal(r, x, {1, 0, 0}); },
          "bytes written");
  measure(b, copy, "random_below", sn + " i32", bytes, [&](vk::Recorder& r) { ops::random_below(r, i, {1, 0, 0}, 1000003); },
          "bytes written");
}

Registration reg_elementwise("elementwise", 10, elementwise);
Registration reg_layout("layout", 10, layout);
Registration reg_random("random", 10, random);

}  // namespace
}  // namespace dvs::bench
