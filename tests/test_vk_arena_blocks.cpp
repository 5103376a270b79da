// Arenas over several blocks (each at most one allocation), memory going back to the driver when freed, and
// the measured peak of reserved memory; the golden transformer under a tiny allocation limit.
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <span>
#include <vector>

#include "io/npy.hpp"
#include "models/activation_plan.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "pipeline/transformer_denoiser.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

using test::GpuTest;
constexpr VkDeviceSize KiB = 1024;

// f32 tensors of about 40, 30 and 50 KiB, odd lengths.
const std::vector<int64_t> kElems = {10243, 7681, 12801};

// Counts kElems as a model's plan would, under the allocation limit in force.
vk::ArenaLayout counted(vk::Allocator& a) {
  models::ActivationPlan p(a.alignment(), a.max_allocation(), "test arena");
  for (int64_t n : kElems) p.make({n});
  EXPECT_EQ(p.bytes(), p.layout().bytes());
  return p.layout();
}

// The block of `arena` holding `v`, or -1; fails when `v` leaves that block.
int block_of(const vk::Arena& arena, const vk::BufferView& v) {
  for (size_t i = 0; i < arena.blocks(); ++i) {
    const vk::BufferView& b = arena.block(i).view();
    if (b.buffer == v.buffer && v.offset >= b.offset && v.offset < b.offset + b.size) {
      EXPECT_LE(v.offset + v.size, b.offset + b.size) << "view straddles the end of block " << i;
      return int(i);
    }
  }
  ADD_FAILURE() << "view outside every block";
  return -1;
}

TEST_F(GpuTest, ArenaSpansBlocksUnderTheAllocationLimit) {
  vk::Allocator a(ctx());  // its own, so that its stats are the arena's alone
  const VkDeviceSize al = a.alignment();
  auto aligned = [&](int64_t n) { return (VkDeviceSize(n) * 4 + al - 1) / al * al; };
  {  // Under the device's limits the tensors fit one allocation: one block, no packing loss.
    const vk::ArenaLayout one = counted(a);
    EXPECT_EQ(one.blocks, std::vector<VkDeviceSize>{aligned(kElems[0]) + aligned(kElems[1]) + aligned(kElems[2])});
    vk::Arena single(a, one, "test arena");
    EXPECT_EQ(single.blocks(), 1u);
  }
  test::ScopedLimits limits(ctx(), "alloc=64KiB");
  ASSERT_EQ(a.max_allocation(), 64 * KiB);
  // 40 + 30 KiB exceed one 64 KiB block, 30 + 50 KiB too: three blocks, each as large as its tensor.
  const vk::ArenaLayout layout = counted(a);
  EXPECT_EQ(layout.blocks, (std::vector<VkDeviceSize>{aligned(kElems[0]), aligned(kElems[1]), aligned(kElems[2])}));
  const VkDeviceSize bytes = layout.bytes();

  const uint64_t in_use = a.stats().bytes_in_use;
  vk::Arena arena(a, layout, "test arena");
  ASSERT_EQ(arena.blocks(), 3u);
  EXPECT_EQ(arena.capacity(), bytes);
  EXPECT_EQ(a.stats().bytes_in_use - in_use, bytes) << "the arena reserves exactly what the plan counted";

  std::vector<vk::BufferView> views;
  for (int round = 0; round < 2; ++round) {  // the second round, after reset(), reuses the same blocks
    arena.reset();
    models::ActivationPlan p(arena);
    for (size_t i = 0; i < kElems.size(); ++i) {
      const Tensor t = p.make({kElems[i]});
      const vk::BufferView& v = t.buffer();
      EXPECT_EQ(v.size, VkDeviceSize(kElems[i]) * 4);
      EXPECT_EQ(block_of(arena, v), int(i)) << "tensor " << i;
      EXPECT_EQ(v.offset % al, 0u);
      if (round == 0) {
        views.push_back(v);
      } else {
        EXPECT_EQ(v.buffer, views[i].buffer);
        EXPECT_EQ(v.offset, views[i].offset);
      }
    }
    EXPECT_EQ(arena.used(), bytes);
  }
  EXPECT_EQ(arena.peak(), bytes);
  EXPECT_EQ(a.stats().bytes_in_use - in_use, bytes) << "reset() keeps the blocks, allocates nothing";
}

TEST_F(GpuTest, ArenaTensorOverOneAllocationIsAClearError) {
  test::ScopedLimits limits(ctx(), "alloc=64KiB");
  vk::Allocator& a = ctx().allocator();
  models::ActivationPlan p(a.alignment(), a.max_allocation(), "test arena");
  p.make({1001});
  // 20011 f32 = 78.2 KiB: more than one 64 KiB allocation holds.
  test::expect_error([&] { p.make({1, 20011}); },
                     {"test arena", "1x20011", "f32", "78.2 KiB", "maxMemoryAllocationSize 64.0 KiB", "--height"});
  vk::Arena arena(a, 64 * KiB, "test arena");
  test::expect_error([&] { arena.alloc(20011 * 4); }, {"test arena", "78.2 KiB", "maxMemoryAllocationSize 64.0 KiB"});
}

TEST_F(GpuTest, FreedBlocksGoBackToTheDriver) {
  vk::Allocator a(ctx());  // its own: its blocks are this test's alone
  const VkDeviceSize block = 64 * KiB;
  {
    test::ScopedLimits limits(ctx(), "alloc=64KiB");
    ASSERT_EQ(a.block_size(), block) << "the standard block follows the limit in force";
    vk::Buffer small = a.allocate(1000, vk::MemoryUse::device, "small");
    EXPECT_EQ(a.stats().blocks, 1u);
    auto arena = std::make_unique<vk::Arena>(a, counted(a), "test arena");
    // The arena's 40 KiB block fits beside the small buffer; its 30 and 50 KiB blocks need a block each.
    EXPECT_EQ(a.stats().blocks, 3u);
    EXPECT_EQ(a.stats().bytes_reserved, 3 * block);
    EXPECT_EQ(a.stats().peak_bytes_reserved, 3 * block);
    const uint64_t heap_before = a.device_memory_reserved();
    arena = nullptr;
    EXPECT_EQ(a.stats().blocks, 2u) << "two blocks emptied: one kept as the spare, one freed";
    EXPECT_EQ(a.stats().bytes_reserved, 2 * block);
    EXPECT_LT(a.device_memory_reserved(), heap_before);
    small = vk::Buffer();
    EXPECT_EQ(a.stats().blocks, 1u) << "one spare standard block per use at most";
    EXPECT_EQ(a.stats().bytes_reserved, block);
    EXPECT_EQ(a.stats().bytes_in_use, 0u);
    EXPECT_EQ(a.stats().peak_bytes_reserved, 3 * block) << "the peak stays";
    { vk::Buffer again = a.allocate(3000, vk::MemoryUse::device, "again"); }
    EXPECT_EQ(a.stats().blocks, 1u) << "the spare serves the next small buffer";
    { vk::Buffer up = a.allocate(5000, vk::MemoryUse::upload, "upload"); }
    EXPECT_EQ(a.stats().blocks, 2u) << "staging keeps a spare of its own";
  }
  // The limit is gone: the standard block is larger again, and a 64 KiB spare goes once it empties.
  ASSERT_GT(a.block_size(), block);
  { vk::Buffer up = a.allocate(5000, vk::MemoryUse::upload, "upload"); }
  EXPECT_EQ(a.stats().blocks, 1u) << "the upload spare was cut for the old limit";
  a.reset_peak();
  EXPECT_EQ(a.stats().peak_bytes_reserved, block);
  {
    test::ScopedLimits limits(ctx(), "alloc=64KiB");
    vk::Buffer b1 = a.allocate(60 * KiB + 3, vk::MemoryUse::device, "b1");  // into the device spare
    vk::Buffer b2 = a.allocate(60 * KiB + 5, vk::MemoryUse::device, "b2");  // a new block
    EXPECT_EQ(a.stats().blocks, 2u);
  }
  EXPECT_EQ(a.stats().peak_bytes_reserved, 2 * block) << "the peak since reset_peak";
  EXPECT_EQ(a.stats().bytes_reserved, block);
}

class ArenaModels : public GpuTest {
 protected:
  std::filesystem::path pack() const { return std::filesystem::path(test::golden_dir()); }
  Tensor upload(const std::string& rel) { return Tensor::upload(ctx(), read_npy(pack() / rel)); }
  // The smallest allocation limit (a multiple of 4 KiB) under which counting() succeeds: every activation
  // tensor fits one allocation. The golden model is tiny: 256 KiB holds its whole arena, so the test cuts
  // blocks this small to make the arena span several.
  template <class F>
  std::string tightest_limit(F&& counting) {
    for (int kib = 64; kib <= 4096; kib += 4) {  // DVS_LIMITS' floor: 64 KiB
      const std::string spec = "alloc=" + std::to_string(kib) + "KiB";
      test::ScopedLimits limits(ctx(), spec);
      try {
        counting();
        return spec;
      } catch (const Error&) {
      }
    }
    ADD_FAILURE() << "no allocation limit up to 4 MiB holds every activation tensor";
    return "alloc=4MiB";
  }
};

// Rows of `t` [1, ...] repeated `n` times: [n, ...].
HostTensor repeat_rows(const HostTensor& t, int64_t n) {
  HostTensor r = t;
  r.shape[0] = n;
  r.data.clear();
  for (int64_t i = 0; i < n; ++i) r.data.insert(r.data.end(), t.data.begin(), t.data.end());
  return r;
}

TEST_F(ArenaModels, TransformerOverArenaBlocksIsBitwiseTheSame) {
  models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");  // weights under the device's limits
  const HostTensor lat = read_npy(pack() / "transformer/hidden_states.npy");  // [1, F, C, H, W]
  const HostTensor txt = read_npy(pack() / "transformer/encoder_hidden_states.npy");
  const Shape& s = lat.shape;
  const int64_t L = txt.shape[1];
  // A batch large enough that the arena is several times DVS_LIMITS' smallest allocation (64 KiB).
  int64_t B = 1;
  while (tr.arena_bytes(B, s[1], s[3], s[4], L) < 4 * 64 * KiB) B += 2;
  const Tensor latent = Tensor::upload(ctx(), repeat_rows(lat, B));
  const Tensor text = Tensor::upload(ctx(), repeat_rows(txt, B));
  const std::vector<float> t(size_t(B), 999.0f);
  const HostTensor ref = tr.forward(latent, text, t).download(ctx());
  auto count = [&] { return tr.arena_bytes(B, s[1], s[3], s[4], L); };
  const VkDeviceSize one_block = count();
  const std::string tight = tightest_limit(count);
  for (const std::string& spec : {std::string("alloc=256KiB"), tight}) {
    test::ScopedLimits limits(ctx(), spec);
    const VkDeviceSize limit = ctx().allocator().max_allocation();
    const VkDeviceSize bytes = count();
    if (spec == tight) ASSERT_GT(one_block, limit) << "the arena must span several blocks under " << spec;
    if (one_block <= limit) {
      EXPECT_EQ(bytes, one_block) << spec << ": activations that fit one allocation take one block";
    } else {
      // Several blocks; not necessarily as many bytes as one block: the token chunks are sized from the allocation
      // limit (models/cogvideox token chunking), so a lower limit also means smaller per-token activations.
      EXPECT_GT(bytes, limit) << spec << ": several blocks";
    }
    const HostTensor got = tr.forward(latent, text, t).download(ctx());
    ASSERT_EQ(got.shape, ref.shape);
    EXPECT_EQ(got.data, ref.data) << spec << ": the forward over arena blocks differs from the one-block forward";
  }
}

// The pipeline's inversion denoiser (batch 1) is gone before the CFG one (batch 2) is made (denoise_stages.cpp:
// each lives in its loop's function), and a denoiser holds its arena no longer than it lives: the run's peak
// is the larger arena, not both. (That freed blocks go back to the driver: FreedBlocksGoBackToTheDriver.)
TEST_F(ArenaModels, DenoiserArenaGoesWithTheDenoiser) {
  models::CogVideoXTransformer tr(ctx(), pack() / "model" / "transformer");
  const HostTensor lat = read_npy(pack() / "transformer/hidden_states.npy");  // [1, F, 2C, H, W]
  const Shape& s = lat.shape;
  const HostTensor txt = read_npy(pack() / "transformer/encoder_hidden_states.npy");
  const int64_t L = txt.shape[1];
  const Tensor image = Tensor::zeros(ctx(), {s[1], s[2] / 2, s[3], s[4]}, DType::f32, "image latent");
  const Tensor text1 = Tensor::upload(ctx(), txt);
  const Tensor text2 = Tensor::zeros(ctx(), {2, L, txt.shape[2]}, DType::f32, "text");
  tr.rope_tables(s[1], s[3], s[4]);  // cached by the model for the run: made before measuring
  tr.positional_embedding(s[1], s[3], s[4], L);
  const VkDeviceSize arena1 = tr.arena_bytes(1, s[1], s[3], s[4], L), arena2 = tr.arena_bytes(2, s[1], s[3], s[4], L);
  vk::Allocator& a = ctx().allocator();
  const uint64_t before = a.stats().bytes_in_use;
  { TransformerDenoiser inversion(ctx(), tr, image, text1, 1); }
  EXPECT_EQ(a.stats().bytes_in_use, before) << "the batch-1 denoiser left memory behind";
  a.reset_peak();
  { TransformerDenoiser guided(ctx(), tr, image, text2, 2); }
  const uint64_t peak = a.stats().peak_bytes_in_use - before;
  EXPECT_GE(peak, arena2);
  EXPECT_LT(peak, arena1 + arena2) << "the guided arena came on top of the inversion arena";
}

}  // namespace
}  // namespace dvs
