// Weight streaming (models/block_stream.hpp, `--weights stream`): a model whose block weights stream from host
// memory through device slots gives the same bytes as the same model with every weight resident (tiny and mid
// sizes, the transformer and T5, with the per-token work cut into many chunks too); with device memory below the
// resident weights the resident model cannot load and the streamed one runs; and the uploads are scheduled to
// overlap the compute: on the timelines (the context's counts compute submissions, the upload queue's counts
// uploads), block j+1's upload is submitted before block j's compute and does not wait for it, block j's
// compute waits for block j's upload only, and an upload into a slot waits for the compute that last read it.
// Lavapipe runs one queue, so the overlap itself (copy engine beside the compute) shows only on a GPU; what
// these tests prove is the dependency graph that lets a GPU overlap them.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <filesystem>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "models/block_stream.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/lora.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/random/tiny_model.hpp"
#include "support/gpu.hpp"
#include "support/lora_adapter.hpp"
#include "support/scoped_limits.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"
#include "vk/device_limits.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using models::StreamEvent;
using models::WeightResidency;

// Tiny: the unit-test model (2 blocks, width 32). Mid: 4 blocks of width 256 (4 heads x 64), a 4096-wide text
// input, 226 text tokens and a 13 x 30 x 44 latent: the real model's structure at a fifth of its width.
models::TinyModelSpec tiny_spec() {
  models::TinyModelSpec s;
  s.seed = 3;
  s.dtype = DType::bf16;
  return s;
}
models::TinyModelSpec mid_spec() {
  models::TinyModelSpec s = tiny_spec();
  s.layers = 4, s.heads = 4, s.head_dim = 64, s.time_embed_dim = 512, s.text_len = 226;
  s.sample_frames = 49, s.sample_height = 30, s.sample_width = 44;
  s.t5_layers = 3, s.t5_heads = 8, s.t5_d_kv = 64, s.t5_d_model = 512, s.t5_d_ff = 1024, s.vocab = 1000;
  return s;
}

HostTensor host_normals(const Shape& shape, uint32_t seed) {
  HostTensor h(shape, DType::f32);
  std::mt19937 rng(seed);
  std::normal_distribution<float> n;
  for (int64_t i = 0; i < h.numel(); ++i) h.as<float>()[i] = n(rng);
  return h;
}

class WeightStream : public test::GpuTest {
 protected:
  fs::path model(const std::string& name, const models::TinyModelSpec& spec) {
    const fs::path dir = fs::temp_directory_path() / ("dvs_weight_stream_" + name + "_" + std::to_string(::getpid()));
    if (!fs::exists(dir / "transformer" / "config.json")) models::write_tiny_model(dir, spec);
    dirs_.push_back(dir);
    return dir;
  }
  void TearDown() override {
    for (const auto& d : dirs_) fs::remove_all(d);
    test::GpuTest::TearDown();
  }
  Tensor normals(const Shape& shape, uint32_t seed) { return Tensor::upload(ctx(), host_normals(shape, seed), "input"); }
  // One forward of the transformer in `dir` with its block weights as `residency`; the output's bytes.
  std::vector<uint8_t> transformer_bytes(const fs::path& dir, WeightResidency residency, int64_t batch, int64_t frames,
                                         std::vector<StreamEvent>* events = nullptr) {
    models::CogVideoXTransformer tr(ctx(), dir / "transformer", residency);
    EXPECT_EQ(tr.residency(), residency);
    const std::vector<uint8_t> bytes = forward_bytes(tr, batch, frames);
    if (events && tr.stream()) *events = tr.stream()->events();
    return bytes;
  }
  std::vector<uint8_t> forward_bytes(models::CogVideoXTransformer& tr, int64_t batch, int64_t frames) {
    const auto& c = tr.config();
    const Tensor lat = normals({batch, frames, c.in_channels, c.sample_height, c.sample_width}, 1);
    const Tensor txt = normals({batch, c.max_text_seq_length, c.text_embed_dim}, 2);
    const std::vector<float> t{999.0f, 321.0f};
    const Tensor y = tr.forward(lat, txt, std::span<const float>(t.data(), size_t(batch)));
    const HostTensor h = y.download(ctx());
    return std::vector<uint8_t>(h.data.begin(), h.data.end());
  }
  std::vector<uint8_t> t5_bytes(const fs::path& dir, WeightResidency residency) {
    models::T5Encoder t5(ctx(), dir / "text_encoder", residency);
    std::vector<std::vector<int32_t>> ids(2, std::vector<int32_t>(37));
    for (size_t i = 0; i < 37; ++i) ids[0][i] = int32_t((i * 7) % 100), ids[1][i] = int32_t((i * 13 + 5) % 100);
    const HostTensor h = t5.encode(ids).download(ctx());
    return std::vector<uint8_t>(h.data.begin(), h.data.end());
  }

  std::vector<fs::path> dirs_;
};

void expect_same_bytes(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  size_t differ = 0;
  for (size_t i = 0; i < a.size(); ++i) differ += a[i] != b[i];
  EXPECT_EQ(differ, 0u) << what << ": " << differ << " of " << a.size() << " bytes differ";
}

TEST_F(WeightStream, TinyTransformerStreamedIsByteIdentical) {
  const fs::path dir = model("tiny", tiny_spec());
  const auto resident = transformer_bytes(dir, WeightResidency::resident, 2, 3);
  expect_same_bytes(resident, transformer_bytes(dir, WeightResidency::stream, 2, 3), "tiny transformer, batch 2");
  // The outputs are not trivially equal (a model that ignored its weights would pass the comparison).
  EXPECT_NE(resident, transformer_bytes(fs::path(model("tiny_other", [] {
                                          auto s = tiny_spec();
                                          s.seed = 4;
                                          return s;
                                        }())),
                                        WeightResidency::resident, 2, 3));
}

TEST_F(WeightStream, TinyTransformerManyTokenChunksStreamedIsByteIdentical) {
  // Bindings of 4 KiB: the FFN state of 64 tokens x 128 columns x 2 rows is 64 KiB, so the per-token work runs in
  // chunks of 8 tokens (the RoPE row step of head_dim 16), more than 10 per block.
  const fs::path dir = model("tiny", tiny_spec());
  test::ScopedLimits small(ctx(), "binding=4KiB");
  const auto& caps = ctx().caps();
  const auto cfg = models::CogVideoXTransformerConfig::from_json(
      nlohmann::json::parse(std::ifstream(dir / "transformer" / "config.json")));
  const int64_t S = cfg.max_text_seq_length + 3 * (cfg.sample_height / 2) * (cfg.sample_width / 2);
  const int64_t chunk = models::CogVideoXTransformer::token_chunk(cfg, 2, S, caps.max_storage_buffer_range);
  EXPECT_LE(chunk * 4, S) << "the limits must cut the sequence into several chunks";
  const auto resident = transformer_bytes(dir, WeightResidency::resident, 2, 3);
  expect_same_bytes(resident, transformer_bytes(dir, WeightResidency::stream, 2, 3), "tiny transformer, small chunks");
}

// The token chunks against the unchunked call, with LoRA on a chunked (q, the output projection) and an unchunked
// (k) projection: equal within rounding (the chunks' GEMMs may pick other kernel shapes), for the streamed model
// too. A chunk that read or wrote the wrong rows (of xn, h, the RoPE table or the LoRA scratch) would differ by O(1).
TEST_F(WeightStream, TokenChunksAndLoraMatchTheWholeSequence) {
  const fs::path dir = model("tiny", tiny_spec());
  const fs::path lora = test::write_lora_adapter(
      dir, {"transformer_blocks.0.attn1.to_q", "transformer_blocks.1.attn1.to_k", "transformer_blocks.1.attn1.to_out.0"},
      7, 0.5f);
  auto forward = [&](WeightResidency residency) {
    models::CogVideoXTransformer tr(ctx(), dir / "transformer", residency);
    tr.set_lora(models::load_lora(ctx(), lora, 0.8f));
    const auto& c = tr.config();
    const Tensor lat = normals({2, 3, c.in_channels, c.sample_height, c.sample_width}, 1);
    const Tensor txt = normals({2, c.max_text_seq_length, c.text_embed_dim}, 2);
    const std::vector<float> t{999.0f, 321.0f};
    return tr.forward(lat, txt, std::span<const float>(t.data(), 2)).download(ctx()).to_f32();
  };
  const std::vector<float> whole = forward(WeightResidency::resident);
  test::ScopedLimits small(ctx(), "binding=4KiB");
  for (const WeightResidency r : {WeightResidency::resident, WeightResidency::stream}) {
    const std::vector<float> chunked = forward(r);
    ASSERT_EQ(chunked.size(), whole.size());
    double err = 0, top = 0;
    for (size_t i = 0; i < whole.size(); ++i) {
      err = std::max(err, double(std::abs(chunked[i] - whole[i])));
      top = std::max(top, double(std::abs(whole[i])));
    }
    EXPECT_LE(err, 1e-5 * top) << models::residency_name(r) << ": chunked vs whole, max |diff| " << err;
  }
}

TEST_F(WeightStream, MidTransformerStreamedIsByteIdentical) {
  // Under forced limits its chunks are 16 tokens (minutes); the tiny tests take those paths, the schedule and
  // budget tests below stream this model's blocks in several pieces there.
  if (ctx().caps().forced_limits.any()) GTEST_SKIP() << "the mid size at the default limits only";
  const fs::path dir = model("mid", mid_spec());
  const auto resident = transformer_bytes(dir, WeightResidency::resident, 1, 4);
  expect_same_bytes(resident, transformer_bytes(dir, WeightResidency::stream, 1, 4), "mid transformer, 4 x 30 x 44");
}

TEST_F(WeightStream, BlocksLargerThanOneAllocationStreamInPieces) {
  // 2 MiB allocations: the mid model's blocks (4.7 MB of bf16 weights each) are packed over 3 pieces per slot.
  const fs::path dir = model("mid", mid_spec());
  test::ScopedLimits small(ctx(), "alloc=2MiB");
  const auto resident = transformer_bytes(dir, WeightResidency::resident, 1, 1);
  models::CogVideoXTransformer tr(ctx(), dir / "transformer", WeightResidency::stream);
  EXPECT_GE(tr.stream()->slot_pieces(), 3u);
  EXPECT_GT(tr.stream()->slot_bytes(), ctx().caps().max_memory_allocation_size);
  expect_same_bytes(resident, transformer_bytes(dir, WeightResidency::stream, 1, 1), "mid transformer in pieces");
}

TEST_F(WeightStream, T5StreamedIsByteIdentical) {
  const fs::path tiny = model("tiny", tiny_spec());
  expect_same_bytes(t5_bytes(tiny, WeightResidency::resident), t5_bytes(tiny, WeightResidency::stream), "tiny T5");
  const fs::path mid = model("mid", mid_spec());
  expect_same_bytes(t5_bytes(mid, WeightResidency::resident), t5_bytes(mid, WeightResidency::stream), "mid T5");
}

TEST_F(WeightStream, UploadsAreScheduledBesideTheCompute) {
  const fs::path dir = model("mid", mid_spec());
  std::vector<StreamEvent> ev;
  transformer_bytes(dir, WeightResidency::stream, 1, 2, &ev);
  const int64_t blocks = mid_spec().layers;
  const int slots = 2;
  // Per block: its upload and its compute (the first segment that reads it), by position in submission order.
  std::vector<int> up(size_t(blocks), -1), comp(size_t(blocks), -1);
  for (size_t i = 0; i < ev.size(); ++i) {
    auto& where = ev[i].kind == StreamEvent::Kind::upload ? up : comp;
    ASSERT_EQ(where[size_t(ev[i].block)], -1) << "block " << ev[i].block << " appears twice";
    where[size_t(ev[i].block)] = int(i);
  }
  for (int64_t j = 0; j < blocks; ++j) {
    ASSERT_GE(up[size_t(j)], 0) << "block " << j << " was never uploaded";
    ASSERT_GE(comp[size_t(j)], 0) << "block " << j << " never computed";
    const StreamEvent& u = ev[size_t(up[size_t(j)])];
    const StreamEvent& c = ev[size_t(comp[size_t(j)])];
    EXPECT_EQ(u.slot, uint32_t(j % slots));
    EXPECT_EQ(c.slot, u.slot);
    // Block j's compute waits for block j's upload, not for a later one.
    EXPECT_EQ(c.waits_for, u.value) << "block " << j;
    EXPECT_LT(up[size_t(j)], comp[size_t(j)]) << "block " << j << " computes before its upload was submitted";
    if (j + 1 < blocks) {
      const StreamEvent& next = ev[size_t(up[size_t(j + 1)])];
      // Overlap: block j+1's upload goes out before block j's compute and does not wait for it.
      EXPECT_LT(up[size_t(j + 1)], comp[size_t(j)]) << "block " << j + 1 << "'s upload waits for block " << j << "'s submission";
      EXPECT_LT(next.waits_for, c.value) << "block " << j + 1 << "'s upload waits on the GPU for block " << j << "'s compute";
      EXPECT_LT(c.waits_for, next.value) << "block " << j << "'s compute waits for block " << j + 1 << "'s upload";
    }
    if (j + slots < blocks) {
      // Slot reuse: block j+slots overwrites block j's slot only after every segment of block j (the compute
      // submitted before block j+1 starts) has run.
      const StreamEvent& reuse = ev[size_t(up[size_t(j + slots)])];
      const StreamEvent& after = ev[size_t(comp[size_t(j + 1)])];
      EXPECT_GE(reuse.waits_for, after.value - 1) << "block " << j + slots << " overwrites block " << j << "'s slot too early";
      EXPECT_GT(reuse.waits_for, c.value - 1) << "block " << j + slots << " does not wait for block " << j << "'s compute";
    }
  }
}

// The same schedule on the device's clock (GPU timestamps written by the uploads' and the compute's own commands,
// not the host's wall clock): block j computes only after its upload has finished; block j + 1's upload starts
// before block j's compute has ended (it does not wait for it: on a GPU's copy engine it runs beside it, on one
// queue, as here, ahead of it); an upload into a slot starts only after the compute that last read the slot has
// ended. Timestamps of two queues do not compare, so a device with a transfer queue skips this (the schedule test
// above still runs there). Fails when the next block's upload is made at that block's start instead of one ahead.
TEST_F(WeightStream, UploadsRunAheadOfTheComputeOnTheDevicesClock) {
  if (ctx().has_transfer_queue()) GTEST_SKIP() << "uploads on a transfer queue: its timestamps do not compare";
  const fs::path dir = model("mid", mid_spec());
  models::CogVideoXTransformer tr(ctx(), dir / "transformer", WeightResidency::stream);
  tr.stream()->record_timestamps();
  const std::vector<uint8_t> streamed = forward_bytes(tr, 1, 2);
  const std::vector<models::BlockTimes> t = tr.stream()->block_times();
  const size_t blocks = size_t(mid_spec().layers), slots = 2;
  ASSERT_EQ(t.size(), blocks);
  for (size_t j = 0; j < blocks; ++j) {
    EXPECT_LE(t[j].upload_start, t[j].upload_end) << "block " << j;
    EXPECT_LE(t[j].upload_end, t[j].compute_start) << "block " << j << " computes before its upload has finished";
    if (j + 1 == blocks) continue;
    EXPECT_LT(t[j].compute_start, t[j].compute_end) << "block " << j;
    EXPECT_LT(t[j + 1].upload_start, t[j].compute_end) << "block " << j + 1 << "'s upload waited for block " << j;
    if (j + slots < blocks)
      EXPECT_GE(t[j + slots].upload_start, t[j].compute_end) << "block " << j + slots << " overwrote block " << j
                                                             << "'s slot while it computed";
  }
  // The marks change no byte.
  expect_same_bytes(transformer_bytes(dir, WeightResidency::resident, 1, 2), streamed, "streamed with timestamps");
}

TEST_F(WeightStream, DeviceMemoryBelowTheWeightsNeedsStreaming) {
  // A context of its own, so that nothing else holds device memory, with allocations of at most 8 MiB (the
  // allocator's blocks, the granularity of its budget check). The model: the mid one with 8 blocks, so that its
  // resident weights clearly exceed what the streamed call needs (2 slots, its other weights and one call).
  models::TinyModelSpec spec = mid_spec();
  spec.layers = 8;
  const fs::path dir = model("mid8", spec);
  const std::string limits = "alloc=8MiB";
  vk::Context own;
  own.override_limits(vk::parse_limit_overrides(limits, "test"));
  auto run = [&](models::CogVideoXTransformer& tr) {
    const auto& c = tr.config();
    const Tensor lat = Tensor::upload(own, host_normals({1, 1, c.in_channels, c.sample_height, c.sample_width}, 1));
    const Tensor txt = Tensor::upload(own, host_normals({1, c.max_text_seq_length, c.text_embed_dim}, 2));
    const float t = 999.0f;
    const HostTensor y = tr.forward(lat, txt, std::span<const float>(&t, 1)).download(own);
    return std::vector<uint8_t>(y.data.begin(), y.data.end());
  };
  std::vector<uint8_t> reference;
  uint64_t resident_need = 0, streamed_need = 0;
  {
    models::CogVideoXTransformer tr(own, dir / "transformer", WeightResidency::resident);
    resident_need = own.allocator().device_memory_reserved();  // the weights alone
    reference = run(tr);
  }
  {
    models::CogVideoXTransformer tr(own, dir / "transformer", WeightResidency::stream);
    own.allocator().reset_peak();
    run(tr);
    streamed_need = own.allocator().stats().peak_bytes_reserved;
  }
  ASSERT_LT(streamed_need + (8u << 20), resident_need) << "the streamed call must need clearly less than the weights";
  const uint64_t budget = (streamed_need + resident_need) / 2;
  own.override_limits(vk::parse_limit_overrides(limits + ",memory=" + std::to_string(budget), "test"));
  EXPECT_THROW(models::CogVideoXTransformer(own, dir / "transformer", WeightResidency::resident), vk::DeviceOutOfMemory);
  models::CogVideoXTransformer tr(own, dir / "transformer", WeightResidency::stream);
  const std::vector<uint8_t> streamed = run(tr);
  EXPECT_LE(own.allocator().device_memory_reserved(), budget);
  expect_same_bytes(reference, streamed, "streamed under a budget below the weights");
}

}  // namespace
}  // namespace dvs
