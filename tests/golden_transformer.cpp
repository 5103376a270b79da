// Golden checks of the CogVideoX transformer against the pack's cases transformer_t999 (output and every
// recorded intermediate, to localise errors), transformer_t500, rope (tables built for the latent size) and
// bf16_sharded (transformer half), plus a CFG-style batch of 2 with different text and per-row timesteps.
// Tolerances from cases.json (|ours - golden| <= atol + rtol·|golden|); each check prints its max error.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "support/golden_compare.hpp"
#include "support/pack.hpp"
#include "support/precision_rule.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_linear.hpp"
#include "vk/pipeline.hpp"

namespace fs = std::filesystem;
using dvs::HostTensor;

namespace {

fs::path pack() { return dvs::test::golden_path(); }
using Tol = dvs::test::PackTolerance;
using dvs::test::pack_npy;
using dvs::test::pack_tolerance;

// Compares `ours` (or its row `row` of the outermost dimension) with the pack file `rel`, shapes included, by the
// precision rule for the transformer's ops (support/precision_rule.hpp: the case's tolerance, or 2x PyTorch's bf16
// run under 16-bit-operand kernels).
void expect_close(const std::string& what, const HostTensor& ours, const std::string& rel, Tol tol, int64_t row = -1,
                  unsigned ops = dvs::test::kTextOps) {
  HostTensor part = ours;
  if (row >= 0) {
    part = HostTensor(dvs::Shape(ours.shape.begin() + 1, ours.shape.end()), ours.dtype);
    std::copy_n(ours.data.begin() + long(size_t(row) * part.bytes()), part.bytes(), part.data.begin());
  }
  dvs::test::expect_golden(what, part, rel, tol.atol, tol.rtol, ops);
}

float scalar(const std::string& rel) { return pack_npy(rel).to_f32().at(0); }

class GoldenTransformer : public dvs::test::GpuTest {
 protected:
  dvs::Tensor upload(const std::string& rel) { return dvs::Tensor::upload(ctx(), pack_npy(rel)); }
};

}  // namespace

TEST_F(GoldenTransformer, T999OutputAndIntermediates) {
  dvs::models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");
  const dvs::Tensor latent = upload("transformer/hidden_states.npy");
  const dvs::Tensor text = upload("transformer/encoder_hidden_states.npy");
  const float t = scalar("transformer/timestep_999.npy");
  dvs::models::CogVideoXTaps taps;
  const dvs::Tensor out = tr.forward(latent, text, std::span<const float>(&t, 1), &taps);
  const Tol tol = pack_tolerance("transformer_t999");

  // The RoPE tables the model built for this latent size are the pipeline's (case rope).
  const auto& rope = tr.rope_tables(latent.dim(1), latent.dim(3), latent.dim(4));
  // (tables of the positions: no linear, attention or convolution makes them)
  expect_close("rope cos", rope.first.download(ctx()), "transformer/rope_cos.npy", pack_tolerance("rope"), -1,
               dvs::test::kNoKernelOps);
  expect_close("rope sin", rope.second.download(ctx()), "transformer/rope_sin.npy", pack_tolerance("rope"), -1,
               dvs::test::kNoKernelOps);

  expect_close("t999 time_embedding", taps.time_embedding, "transformer/t999_time_embedding.npy", tol);
  expect_close("t999 patch_embed", taps.patch_embed, "transformer/t999_patch_embed.npy", tol);
  for (size_t i = 0; i < taps.block_hidden.size(); ++i) {
    const std::string b = "transformer/t999_block" + std::to_string(i);
    ASSERT_TRUE(fs::exists(pack() / (b + "_hidden.npy"))) << "the pack has no tap of block " << i << ": " << b;
    expect_close("t999 block" + std::to_string(i) + " hidden", taps.block_hidden[i], b + "_hidden.npy", tol);
    expect_close("t999 block" + std::to_string(i) + " encoder", taps.block_encoder[i], b + "_encoder.npy", tol);
  }
  expect_close("t999 norm_final", taps.norm_final, "transformer/t999_norm_final.npy", tol);
  expect_close("t999 proj_out", taps.proj_out, "transformer/t999_proj_out.npy", tol);
  expect_close("transformer_t999 output", out.download(ctx()), "transformer/output_t999.npy", tol);

  // Where the attention ran on the tensor cores beside tensor-core GEMMs, q, k and v reached it fp16 and head-major
  // through ops::attention_heads (q and k with their norm and RoPE, v without): pipelines of each kind were made.
  bool coopmat_attention = false;
  for (const auto& [note, count] : ctx().kernel_notes())
    coopmat_attention |= note.op == "attention" && note.family == "coopmat";
  if (coopmat_attention && dvs::ops::gemm_activation_dtype(ctx().caps()) == dvs::DType::f16) {
    bool qk = false, v = false;  // spec: WDTYPE, NORM, AFFINE, ROPE, Y_F16, N4
    ctx().pipelines().for_each([&](const dvs::vk::Pipeline& pl) {
      if (pl.name != "nn/attention_heads" || pl.spec.size() < 5 || pl.spec[4] != 1) return;
      qk |= pl.spec[1] == 1 && pl.spec[3] == 1;
      v |= pl.spec[1] == 0 && pl.spec[3] == 0;
    });
    EXPECT_TRUE(qk) << "no fp16 attention_heads pipeline with norm and RoPE (q, k) under tensor-core attention";
    EXPECT_TRUE(v) << "no fp16 attention_heads pipeline without norm or RoPE (v) under tensor-core attention";
  }
}

// Small bindings cut the sequence into token chunks (the text, then several video chunks): each chunk's q (its norm,
// its RoPE rows from its first token, its fp16 head-major copy where the attention runs on tensor cores), its
// attention against every key and its rows of the output must land where the whole-sequence call puts them. The
// pack's sequence is otherwise one video chunk (kMinChunkTokens), as every real-size run is not. (At 8 KiB the FFN's
// first GEMM also splits its columns: an f16 output's column chunks must stay even.)
TEST_F(GoldenTransformer, T999InSeveralTokenChunks) {
  dvs::models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");
  const dvs::Tensor latent = upload("transformer/hidden_states.npy");
  const dvs::Tensor text = upload("transformer/encoder_hidden_states.npy");
  const float t = scalar("transformer/timestep_999.npy");
  const auto& cfg = tr.config();
  const int64_t L = text.dim(1), N = latent.dim(1) * (latent.dim(3) / cfg.patch_size) * (latent.dim(4) / cfg.patch_size);
  dvs::test::ScopedLimits small(ctx(), "binding=8KiB");
  const int64_t chunk = dvs::models::CogVideoXTransformer::token_chunk(cfg, 1, L + N, 8 * 1024);
  ASSERT_LT(2 * chunk, N) << "8 KiB bindings leave the video tokens in fewer than three chunks";
  const dvs::Tensor out = tr.forward(latent, text, std::span<const float>(&t, 1));
  expect_close("transformer_t999 output, " + std::to_string(chunk) + "-token chunks", out.download(ctx()),
               "transformer/output_t999.npy", pack_tolerance("transformer_t999"));
}

TEST_F(GoldenTransformer, T500) {
  dvs::models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");
  const float t = scalar("transformer/timestep_500.npy");
  dvs::models::CogVideoXTaps taps;
  const dvs::Tensor out = tr.forward(upload("transformer/hidden_states.npy"), upload("transformer/encoder_hidden_states.npy"),
                                     std::span<const float>(&t, 1), &taps);
  const Tol tol = pack_tolerance("transformer_t500");
  expect_close("t500 time_embedding", taps.time_embedding, "transformer/t500_time_embedding.npy", tol);
  expect_close("t500 block0 hidden", taps.block_hidden.at(0), "transformer/t500_block0_hidden.npy", tol);
  expect_close("t500 block0 encoder", taps.block_encoder.at(0), "transformer/t500_block0_encoder.npy", tol);
  expect_close("transformer_t500 output", out.download(ctx()), "transformer/output_t500.npy", tol);
}

// CFG-style batch of 2 in one call: row 0 = (text, t500), row 1 = (0.5·text, t999). Row 0 must equal the
// t500 golden; row 1 must equal a batch-1 call on its own inputs (rows must not mix).
TEST_F(GoldenTransformer, BatchOfTwoWithDifferentTextAndTimesteps) {
  dvs::models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");
  const HostTensor lat = pack_npy("transformer/hidden_states.npy");
  const HostTensor txt = pack_npy("transformer/encoder_hidden_states.npy");
  auto stack2 = [](const HostTensor& a, const HostTensor& b) {
    HostTensor r = a;
    r.shape[0] = 2;
    r.data.insert(r.data.end(), b.data.begin(), b.data.end());
    return r;
  };
  HostTensor half = txt;
  for (int64_t i = 0; i < half.numel(); ++i) half.as<float>()[i] *= 0.5f;
  const float ts[2] = {scalar("transformer/timestep_500.npy"), scalar("transformer/timestep_999.npy")};
  const dvs::Tensor out2 = tr.forward(dvs::Tensor::upload(ctx(), stack2(lat, lat)), dvs::Tensor::upload(ctx(), stack2(txt, half)),
                                      std::span<const float>(ts, 2));
  const HostTensor v2 = out2.download(ctx());
  const Tol tol = pack_tolerance("transformer_t500");
  expect_close("batch2 row0 (t500)", v2, "transformer/output_t500.npy", tol, 0);
  const dvs::Tensor out1 = tr.forward(dvs::Tensor::upload(ctx(), lat), dvs::Tensor::upload(ctx(), half),
                                      std::span<const float>(&ts[1], 1));
  HostTensor row1(dvs::Shape(v2.shape.begin() + 1, v2.shape.end()), v2.dtype);
  std::copy_n(v2.data.begin() + long(row1.bytes()), row1.bytes(), row1.data.begin());
  dvs::test::expect_close("batch2 row1 vs batch-1 call", row1, out1.download(ctx()), 1e-6, 1e-6);
}

TEST_F(GoldenTransformer, Bf16Sharded) {
  dvs::models::CogVideoXTransformer tr(ctx(), pack() / "model_bf16" / "transformer");
  // Read as stored (BF16), except the Linear weights where the tensor cores run the GEMMs (kept fp16 there).
  EXPECT_EQ(tr.weights().get("proj_out.weight").dtype(), dvs::ops::gemm_weight_dtype(ctx().caps()));
  EXPECT_EQ(tr.weights().get("proj_out.bias").dtype(), dvs::DType::bf16);
  const float t = scalar("transformer/timestep_999.npy");
  const dvs::Tensor out = tr.forward(upload("transformer/hidden_states.npy"), upload("transformer/encoder_hidden_states.npy"),
                                     std::span<const float>(&t, 1));
  expect_close("bf16_sharded transformer", out.download(ctx()), "bf16_sharded/transformer_output_t999.npy",
               pack_tolerance("bf16_sharded", "transformer"));
}

// Not asserted: forward time at the pack's size (the recording included, as a caller sees it).
TEST_F(GoldenTransformer, ForwardTimeAtPackSize) {
  dvs::models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");
  const dvs::Tensor latent = upload("transformer/hidden_states.npy");
  const dvs::Tensor text = upload("transformer/encoder_hidden_states.npy");
  const float t = 999.0f;
  tr.forward(latent, text, std::span<const float>(&t, 1));  // warm-up: pipelines, tables, arena
  const int reps = 3;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < reps; ++i) tr.forward(latent, text, std::span<const float>(&t, 1));
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / reps;
  std::cout << "[timing] CogVideoX transformer forward " << latent.describe() << " + text " << text.describe() << ": "
            << ms << " ms per call (" << ctx().caps().name << ")\n";
}
