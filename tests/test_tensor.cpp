// Tensors: upload/download round trips for every dtype, views, reshapes, row slices, and .npy files
// through device memory.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "dvs/error.hpp"
#include "io/npy.hpp"
#include "support/gpu.hpp"
#include "tensor/tensor.hpp"

namespace dvs {
namespace {

using test::GpuTest;

HostTensor random_host(Shape shape, DType dtype, uint32_t seed) {
  HostTensor h(std::move(shape), dtype);
  std::mt19937 rng(seed);
  for (auto& b : h.data) b = uint8_t(rng());
  return h;
}

TEST_F(GpuTest, TensorRoundTripEveryDtype) {
  for (DType t : {DType::f32, DType::f16, DType::bf16, DType::i32, DType::u8})
    for (Shape s : {Shape{}, Shape{0}, Shape{1}, Shape{7}, Shape{3, 5, 33}, Shape{2, 1, 129}}) {
      HostTensor h = random_host(s, t, uint32_t(s.size() * 10 + int(t)));
      Tensor d = Tensor::upload(ctx(), h, "test");
      EXPECT_EQ(d.shape(), s);
      EXPECT_EQ(d.dtype(), t);
      EXPECT_EQ(d.bytes(), h.bytes());
      HostTensor back = d.download(ctx());
      EXPECT_EQ(back.data, h.data) << d.describe();
    }
}

TEST_F(GpuTest, TensorViewsAndSlices) {
  HostTensor h(Shape{4, 3}, DType::f32);
  for (int i = 0; i < 12; ++i) h.as<float>()[i] = float(i);
  Tensor t = Tensor::upload(ctx(), h);
  Tensor r = t.rows(1, 2);
  EXPECT_EQ(r.shape(), (Shape{2, 3}));
  HostTensor rh = r.download(ctx());
  for (int i = 0; i < 6; ++i) EXPECT_EQ(rh.as<float>()[i], float(i + 3));
  Tensor flat = t.reshape({12});
  EXPECT_EQ(flat.numel(), 12);
  EXPECT_THROW(t.reshape({5}), Error);
  EXPECT_THROW(t.rows(3, 2), Error);
  EXPECT_EQ(t.dim(-1), 3);
  EXPECT_EQ(t.describe(), "f32[4x3]");
  Tensor z = Tensor::zeros(ctx(), {5, 7}, DType::f32);
  for (float v : z.download(ctx()).to_f32()) EXPECT_EQ(v, 0.0f);
  // A non-owning view over an arena range.
  vk::Arena arena(ctx().allocator(), 4096);
  Tensor a = Tensor::on(arena.alloc(12 * 4), {3, 4}, DType::f32);
  std::vector<float> fill(12, 2.5f);
  a.write(ctx(), HostTensor::from_f32({3, 4}, fill));
  EXPECT_EQ(a.download(ctx()).to_f32()[11], 2.5f);
  EXPECT_THROW(Tensor::on(arena.alloc(8), {3, 4}, DType::f32), Error);
  EXPECT_THROW(a.write(ctx(), h), Error);  // shape mismatch
}

TEST_F(GpuTest, NpyThroughDevice) {
  // A golden file of the pack goes to the device and back unchanged, and writes back identically.
  auto path = std::filesystem::path(test::golden_dir()) / "transformer" / "rope_cos.npy";
  HostTensor h = read_npy(path);
  EXPECT_EQ(h.shape, (Shape{48, 16}));
  HostTensor back = Tensor::upload(ctx(), h).download(ctx());
  auto tmp = std::filesystem::temp_directory_path() / "dvs_test_tensor_roundtrip.npy";
  write_npy(tmp, back);
  HostTensor again = read_npy(tmp);
  std::filesystem::remove(tmp);
  EXPECT_EQ(again.shape, h.shape);
  EXPECT_EQ(again.data, h.data);
}

}  // namespace
}  // namespace dvs
