// The Vulkan runtime on the test device (lavapipe in CI): device choice, memory at its limits, copies,
// dispatches with specialization constants, barrier tracking, replay, the disk pipeline cache, timestamps.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>

#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "vk/memory.hpp"
#include "vk/pipeline.hpp"
#include "vk/profiler.hpp"
#include "vk/recorder.hpp"
#include "vk/shader_registry.hpp"
#include "vk/transfer.hpp"

namespace dvs {
namespace {

using test::GpuTest;

TEST(VkDevices, ListAndSelect) {
  auto devices = vk::list_devices();
  ASSERT_FALSE(devices.empty());
  EXPECT_EQ(vk::select_device(devices, "0"), 0u);
  std::string part = devices[0].name.substr(0, 4);
  for (char& c : part) c = char(std::toupper(static_cast<unsigned char>(c)));  // matching ignores case
  EXPECT_EQ(vk::select_device(devices, part), devices[0].index);
  try {
    vk::select_device(devices, "no-such-gpu-xyz");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-gpu-xyz"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find(devices[0].name), std::string::npos) << "error should list the devices";
  }
  EXPECT_THROW(vk::select_device(devices, "999"), Error);
  std::string report = vk::describe_device(devices[0]);
  EXPECT_NE(report.find("maxStorageBufferRange"), std::string::npos);
  EXPECT_NE(report.find("subgroup size"), std::string::npos);
}

TEST_F(GpuTest, ValidationMessagesAreCaught) {
  // Proves the mechanism that fails tests: an invalid call must produce a message.
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = 0;  // invalid: size must be > 0
  bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  VkBuffer buf = VK_NULL_HANDLE;
  VkResult r = vkCreateBuffer(ctx().device(), &bci, nullptr, &buf);
  if (r == VK_SUCCESS && buf) vkDestroyBuffer(ctx().device(), buf, nullptr);
  EXPECT_FALSE(ctx().validation_messages().empty());
  ctx().clear_validation_messages();
}

TEST_F(GpuTest, AllocationsReuseMemory) {
  auto& a = ctx().allocator();
  uint64_t before = a.stats().bytes_in_use;
  {
    std::vector<vk::Buffer> bufs;
    for (int i = 1; i <= 50; ++i) bufs.push_back(a.allocate(uint64_t(i) * 1237, vk::MemoryUse::device, "t"));
    for (auto& b : bufs) EXPECT_EQ(b.view().offset % a.alignment(), 0u);
    // Distinct buffers never overlap.
    for (size_t i = 0; i < bufs.size(); ++i)
      for (size_t j = i + 1; j < bufs.size(); ++j) {
        const auto &x = bufs[i].view(), &y = bufs[j].view();
        if (x.buffer == y.buffer) { EXPECT_TRUE(x.offset + x.size <= y.offset || y.offset + y.size <= x.offset); }
      }
    bufs.erase(bufs.begin() + 10, bufs.begin() + 30);  // free a hole in the middle
    vk::Buffer again = a.allocate(5000, vk::MemoryUse::device, "t");
    EXPECT_TRUE(again.valid());
  }
  EXPECT_EQ(a.stats().bytes_in_use, before);
  vk::Buffer zero = a.allocate(0, vk::MemoryUse::device, "empty");
  EXPECT_TRUE(zero.valid());
}

// A tensor may be larger than one binding (ops bind bounded sub-ranges of it); binding more than
// maxStorageBufferRange to one dispatch is refused, as is an allocation over maxMemoryAllocationSize.
TEST_F(GpuTest, BindingLimitIsEnforcedAtDispatchNotAllocation) {
  auto& a = ctx().allocator();
  uint64_t limit = ctx().caps().max_storage_buffer_range;
  if (limit > (1ull << 28)) GTEST_SKIP() << "binding limit " << limit << " too large to allocate in a test";
  vk::Buffer over = a.allocate(limit + 16, vk::MemoryUse::device, "one binding and a bit");
  ASSERT_EQ(over.size(), limit + 16);
  vk::Buffer out = a.allocate(1024, vk::MemoryUse::device, "out");
  const vk::Pipeline& copy = ctx().pipelines().get("bench/copy", {});
  const uint32_t n4 = 16;
  vk::Recorder rec(ctx());
  rec.begin();
  rec.dispatch(copy, {over.view().sub(0, limit), out.view()}, &n4, 4, 1);  // at the limit: fine
  try {
    rec.dispatch(copy, {over.view(), out.view()}, &n4, 4, 1);
    FAIL() << "a binding over maxStorageBufferRange was accepted";
  } catch (const Error& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("maxStorageBufferRange"), std::string::npos) << m;
    EXPECT_NE(m.find("bench/copy"), std::string::npos) << m;
  }
  rec.end();
  try {
    a.allocate(ctx().caps().max_memory_allocation_size + 1, vk::MemoryUse::device, "huge");
    FAIL() << "an allocation over maxMemoryAllocationSize was accepted";
  } catch (const Error& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("maxMemoryAllocationSize"), std::string::npos) << m;
    EXPECT_NE(m.find("huge"), std::string::npos) << m;
  }
}

TEST_F(GpuTest, CopyRoundTrips) {
  std::mt19937 rng(1);
  for (bool staging : {false, true}) {
    ctx().transfer().set_force_staging(staging);
    for (size_t bytes : {size_t(1), size_t(7), size_t(4096), size_t(1000003)}) {
      std::vector<uint8_t> in(bytes), out(bytes, 0);
      for (auto& v : in) v = uint8_t(rng());
      vk::Buffer a = ctx().allocator().allocate(bytes), b = ctx().allocator().allocate(bytes);
      ctx().transfer().upload(a.view(), in.data(), bytes);
      ctx().transfer().copy(a.view(), b.view(), bytes);
      ctx().transfer().download(b.view(), out.data(), bytes);
      EXPECT_EQ(in, out) << bytes << " bytes, staging=" << staging;
    }
  }
  // Larger than the staging buffer: moved in chunks.
  size_t big = ctx().transfer().staging_bytes() + 12345;
  std::vector<uint8_t> in(big), out(big);
  for (size_t i = 0; i < big; ++i) in[i] = uint8_t(i * 2654435761u >> 24);
  vk::Buffer buf = ctx().allocator().allocate(big);
  ctx().transfer().upload(buf.view(), in.data(), big);
  ctx().transfer().download(buf.view(), out.data(), big);
  ctx().transfer().set_force_staging(false);
  EXPECT_EQ(in, out);
}

// Scattered pieces between two views that start inside their buffers, as one recorded command.
TEST_F(GpuTest, CopyRegionsScattersPieces) {
  const size_t n = 1000;
  std::vector<uint8_t> in(n), out(n, 0), expected(n, 0);
  for (size_t i = 0; i < n; ++i) in[i] = uint8_t(i * 7 + 3);
  vk::Buffer a = ctx().allocator().allocate(n), b = ctx().allocator().allocate(n);
  ctx().transfer().upload(a.view(), in.data(), n);
  ctx().transfer().fill_zero(b.view());
  const vk::BufferView src = a.view().sub(16, 512), dst = b.view().sub(64, 900);
  const std::vector<VkBufferCopy> regions = {{0, 0, 5}, {100, 7, 33}, {511, 899, 1}, {40, 500, 60}};
  for (const VkBufferCopy& r : regions)
    for (VkDeviceSize i = 0; i < r.size; ++i) expected[64 + r.dstOffset + i] = in[16 + r.srcOffset + i];
  vk::Recorder rec(ctx());
  rec.begin();
  rec.copy_regions(src, dst, regions);
  rec.end();
  rec.submit();
  ctx().transfer().download(b.view(), out.data(), n);
  EXPECT_EQ(out, expected);
  rec.begin();
  const VkBufferCopy outside{500, 0, 13};  // past the end of src
  EXPECT_THROW(rec.copy_regions(src, dst, std::span(&outside, 1)), dvs::Error);
  rec.end();
}

// out = in * scale + offset + bias, through test/spec_constants.
struct SpecProbe {
  uint32_t n;
  float bias;
};

std::vector<float> run_probe(vk::Context& ctx, const std::vector<float>& x, float scale, int offset, float bias,
                             uint32_t local) {
  uint32_t n = uint32_t(x.size());
  vk::Buffer in = ctx.allocator().allocate(n * 4), out = ctx.allocator().allocate(n * 4);
  ctx.transfer().upload(in.view(), x.data(), n * 4);
  uint32_t scale_bits;
  std::memcpy(&scale_bits, &scale, 4);
  uint32_t spec[] = {local, scale_bits, uint32_t(offset)};
  const vk::Pipeline& p = ctx.pipelines().get("test/spec_constants", spec);
  vk::Recorder rec(ctx);
  rec.begin();
  SpecProbe push{n, bias};
  rec.dispatch(p, {in.view(), out.view()}, &push, sizeof push, (n + local - 1) / local);
  rec.submit();
  std::vector<float> y(n);
  ctx.transfer().download(out.view(), y.data(), n * 4);
  return y;
}

TEST_F(GpuTest, DispatchWithSpecializationConstants) {
  std::vector<float> x(501);  // 63 groups of 8: within the smallest forced grid limit (groups=64)
  std::iota(x.begin(), x.end(), -250.0f);
  for (auto [scale, offset, local] : {std::tuple{2.5f, 3, 64u}, std::tuple{-1.0f, -7, 8u}}) {
    auto y = run_probe(ctx(), x, scale, offset, 0.25f, local);
    for (size_t i = 0; i < x.size(); ++i) ASSERT_FLOAT_EQ(y[i], x[i] * scale + float(offset) + 0.25f) << i;
  }
  // Reflection found both bindings, the second writable.
  uint32_t spec[] = {64u, 0x3f800000u, 0u};
  const auto& iface = ctx().pipelines().get("test/spec_constants", spec).iface;
  ASSERT_EQ(iface.bindings.size(), 2u);
  EXPECT_TRUE(iface.bindings[0].read_only);
  EXPECT_FALSE(iface.bindings[1].read_only);
}

TEST_F(GpuTest, BarriersOnlyWhereNeededAndReplay) {
  const uint32_t n = 777;
  std::vector<float> x(n, 1.0f);
  vk::Buffer a = ctx().allocator().allocate(n * 4), b = ctx().allocator().allocate(n * 4),
             c = ctx().allocator().allocate(n * 4), d = ctx().allocator().allocate(n * 4);
  ctx().transfer().upload(a.view(), x.data(), n * 4);
  uint32_t spec[] = {64u, 0x40000000u /* 2.0f */, 1u};
  const vk::Pipeline& p = ctx().pipelines().get("test/spec_constants", spec);
  SpecProbe push{n, 0.0f};
  uint32_t groups = (n + 63) / 64;
  vk::Recorder rec(ctx());
  rec.begin();
  rec.dispatch(p, {a.view(), b.view()}, &push, sizeof push, groups);  // b = 2a+1
  rec.dispatch(p, {a.view(), d.view()}, &push, sizeof push, groups);  // independent: no barrier
  EXPECT_EQ(rec.barrier_count(), 0u);
  rec.dispatch(p, {b.view(), c.view()}, &push, sizeof push, groups);  // reads b: barrier
  EXPECT_EQ(rec.barrier_count(), 1u);
  rec.end();
  rec.submit();
  std::vector<float> y(n);
  ctx().transfer().download(c.view(), y.data(), n * 4);
  for (float v : y) ASSERT_FLOAT_EQ(v, 2 * (2 * 1.0f + 1) + 1);
  // Replay the same recording on new input.
  std::vector<float> x2(n, -3.0f);
  ctx().transfer().upload(a.view(), x2.data(), n * 4);
  rec.submit();
  ctx().transfer().download(c.view(), y.data(), n * 4);
  for (float v : y) ASSERT_FLOAT_EQ(v, 2 * (2 * -3.0f + 1) + 1);
}

// A barrier one command needs must not make the recorder forget the command's other accesses (the third copy
// below got no barrier before: the second's barrier had dropped its read of c). Lavapipe runs commands one
// after the other, so a missing barrier never shows there by value; the barrier count shows it anywhere.
TEST_F(GpuTest, BarrierForOneBindingKeepsTheCommandsOtherAccesses) {
  const VkDeviceSize n = 4096;
  vk::Buffer a = ctx().allocator().allocate(n), b = ctx().allocator().allocate(n), c = ctx().allocator().allocate(n),
             d = ctx().allocator().allocate(n);
  vk::Recorder rec(ctx());
  rec.begin();
  rec.copy(a.view(), b.view(), n);  // reads a
  rec.copy(c.view(), a.view(), n);  // reads c, writes a: waits for the read of a (WAR)
  EXPECT_EQ(rec.barrier_count(), 1u);
  rec.copy(d.view(), c.view(), n);  // writes c, which the command before still reads: must wait too
  EXPECT_EQ(rec.barrier_count(), 2u);
  rec.copy(a.view(), d.view(), n);  // writes d, which the command before reads: waits
  EXPECT_EQ(rec.barrier_count(), 3u);
  rec.end();
}

TEST_F(GpuTest, ArenaBumpsAndResets) {
  vk::Arena arena(ctx().allocator(), 1 << 20);
  vk::BufferView v1 = arena.alloc(1000), v2 = arena.alloc(3);
  EXPECT_EQ(v1.buffer, v2.buffer);
  EXPECT_GE(v2.offset, v1.offset + 1000);
  EXPECT_EQ(v2.offset % ctx().allocator().alignment(), 0u);
  EXPECT_THROW(arena.alloc(2 << 20), Error);
  arena.reset();
  EXPECT_EQ(arena.alloc(16).offset, v1.offset);
  EXPECT_GE(arena.peak(), 1003u);
}

TEST_F(GpuTest, TimestampsPerDispatch) {
  if (!ctx().caps().timestamps) GTEST_SKIP() << "device has no timestamps";
  auto& prof = ctx().profiler();
  bool was = prof.enabled();
  prof.set_enabled(true);
  prof.clear();
  std::vector<float> x(4096, 1.0f);
  run_probe(ctx(), x, 1.0f, 0, 0.0f, 64);
  prof.set_enabled(was);
  ASSERT_EQ(prof.entries().count("test/spec_constants"), 1u);
  EXPECT_EQ(prof.entries().at("test/spec_constants").count, 1u);
  EXPECT_GT(prof.entries().at("test/spec_constants").total_ns, 0.0);
  EXPECT_NE(prof.report().find("test/spec_constants"), std::string::npos);
  prof.clear();
}

class PipelineCacheTest : public GpuTest {
 protected:
  std::filesystem::path file = std::filesystem::temp_directory_path() /
                               ("dvs_pc_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                                "_" + std::to_string(std::rand()) + ".bin");
  void TearDown() override {
    std::filesystem::remove(file);
    GpuTest::TearDown();
  }
  // Opens a second context on the same device with this cache file and builds one pipeline in it.
  vk::CacheLoad open_and_use(std::string* note = nullptr) {
    vk::ContextOptions o;
    o.validation = true;
    o.pipeline_cache_file = file.string();
    vk::Context c(o);
    vk::CacheLoad state = c.pipelines().load_state();
    if (note) *note = c.pipelines().load_note();
    std::vector<float> x(100, 2.0f);
    auto y = run_probe(c, x, 3.0f, 1, 0.0f, 64);
    EXPECT_FLOAT_EQ(y[99], 7.0f);
    EXPECT_TRUE(c.validation_messages().empty());
    return state;
  }
  void corrupt(size_t offset, uint8_t xor_mask) {
    std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(std::streamoff(offset));
    char ch;
    f.get(ch);
    f.seekp(std::streamoff(offset));
    f.put(char(ch ^ xor_mask));
  }
};

TEST_F(PipelineCacheTest, ReusedAcrossContexts) {
  EXPECT_EQ(open_and_use(), vk::CacheLoad::absent);
  ASSERT_TRUE(std::filesystem::exists(file));
  EXPECT_EQ(open_and_use(), vk::CacheLoad::loaded);
}

TEST_F(PipelineCacheTest, CorruptFilesAreIgnored) {
  open_and_use();
  auto size = std::filesystem::file_size(file);
  std::string note;
  corrupt(size - 1, 0xff);  // flip a data byte
  EXPECT_EQ(open_and_use(&note), vk::CacheLoad::rejected);
  EXPECT_NE(note.find("checksum"), std::string::npos) << note;
  // The rejected run wrote a fresh, valid cache.
  EXPECT_EQ(open_and_use(), vk::CacheLoad::loaded);
  std::filesystem::resize_file(file, size / 2);
  EXPECT_EQ(open_and_use(&note), vk::CacheLoad::rejected);
  corrupt(0, 0x20);  // magic
  EXPECT_EQ(open_and_use(&note), vk::CacheLoad::rejected);
  EXPECT_NE(note.find("not a dvs pipeline cache"), std::string::npos) << note;
  open_and_use();
  corrupt(8 + 4 * 4 + VK_UUID_SIZE, 0x01);  // shaders hash: as if the shaders had changed
  EXPECT_EQ(open_and_use(&note), vk::CacheLoad::rejected);
  EXPECT_NE(note.find("shaders"), std::string::npos) << note;
  open_and_use();
  corrupt(8 + 8, 0x01);  // driver version
  EXPECT_EQ(open_and_use(&note), vk::CacheLoad::rejected);
  EXPECT_NE(note.find("driver"), std::string::npos) << note;
  { std::ofstream(file, std::ios::trunc) << "garbage"; }
  EXPECT_EQ(open_and_use(), vk::CacheLoad::rejected);
}

TEST(VkShaders, EmbeddedAndHashed) {
  auto names = vk::shader_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "test/spec_constants"), names.end());
  EXPECT_THROW(vk::find_shader("no/such_shader"), Error);
  EXPECT_NE(vk::shaders_hash(), 0u);
}

}  // namespace
}  // namespace dvs
