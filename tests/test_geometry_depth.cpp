// Depth input: .npy (and .npz where built with libzip), disparity → depth exactly as the official code,
// metric depth as is, and a clear error naming the file for every bad input.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "support/expect_error.hpp"
#include "dvs/error.hpp"
#include "io/depth.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"

#include "support/files.hpp"
#include "io/depth_images.hpp"

#include <zip.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace dvs {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

using dvs::test::expect_error;

HostTensor ramp(Shape s, float lo, float step) {
  HostTensor t(s, DType::f32);
  for (int64_t i = 0; i < t.numel(); ++i) t.as<float>()[i] = lo + step * float(i);
  return t;
}

TEST(GeometryDepth, DisparityToDepthAsOfficial) {
  TempDir d;
  HostTensor disp = ramp({3, 4, 5}, 0.25f, 0.5f);  // global min 0.25, max 0.25 + 59·0.5
  write_npy(d.path / "disp.npy", disp);
  HostTensor z = load_depth(d.path / "disp.npy");
  ASSERT_EQ(z.shape, (Shape{3, 4, 5}));
  const float lo = 0.25f, hi = 0.25f + 59 * 0.5f;
  for (int64_t i = 0; i < z.numel(); ++i) {
    float dn = (disp.as<float>()[i] - lo) / (hi - lo);
    float want = std::clamp(10000.0f / std::max(3900.0f * dn, 1e-5f), 1e-4f, 1e4f);
    EXPECT_EQ(z.as<float>()[i], want) << i;
  }
  EXPECT_EQ(z.as<float>()[0], 1e4f);                      // the farthest point saturates at 10000
  EXPECT_NEAR(z.as<float>()[59], 10000.0 / 3900.0, 1e-6);  // the nearest is 2.5641
  // Metric depth is used as is; [N,1,H,W] and float16 are accepted.
  HostTensor metric = ramp({2, 1, 3, 3}, 1.0f, 0.25f);
  write_npy(d.path / "metric.npy", metric);
  DepthOptions o;
  o.values = DepthValues::depth;
  HostTensor m = load_depth(d.path / "metric.npy", o);
  ASSERT_EQ(m.shape, (Shape{2, 3, 3}));
  for (int64_t i = 0; i < m.numel(); ++i) EXPECT_EQ(m.as<float>()[i], metric.as<float>()[i]);
  HostTensor h({1, 2, 2}, DType::f16);
  for (int i = 0; i < 4; ++i) reinterpret_cast<uint16_t*>(h.data.data())[i] = f32_to_f16(1.5f + float(i));
  write_npy(d.path / "half.npy", h);
  HostTensor hz = load_depth(d.path / "half.npy", o);
  EXPECT_EQ(hz.as<float>()[3], 4.5f);
}

TEST(GeometryDepth, BadInputsNameTheFile) {
  TempDir d;
  HostTensor nan = ramp({2, 3, 3}, 1, 1);
  nan.as<float>()[9 + 4] = std::nanf("");
  write_npy(d.path / "nan.npy", nan);
  expect_error([&] { load_depth(d.path / "nan.npy"); }, {"nan.npy", "frame 1", "NaN", "row 1, column 1"});
  HostTensor inf = ramp({1, 2, 2}, 1, 1);
  inf.as<float>()[2] = INFINITY;
  write_npy(d.path / "inf.npy", inf);
  expect_error([&] { load_depth(d.path / "inf.npy"); }, {"inf.npy", "infinite"});
  write_npy(d.path / "zero.npy", HostTensor({0, 4, 4}, DType::f32));
  expect_error([&] { load_depth(d.path / "zero.npy"); }, {"zero.npy", "zero frames"});
  write_npy(d.path / "rank2.npy", ramp({4, 4}, 1, 1));
  expect_error([&] { load_depth(d.path / "rank2.npy"); }, {"rank2.npy", "[N,H,W]"});
  // Integer depth maps (16-bit tools, i32 after numpy's widening) are read as their values.
  HostTensor ints({1, 2, 2}, DType::i32);
  for (int i = 0; i < 4; ++i) ints.as<int32_t>()[i] = 40000 + i;
  write_npy(d.path / "int.npy", ints);
  const HostTensor as_float = read_depth_array(d.path / "int.npy");
  ASSERT_EQ(as_float.dtype, DType::f32);
  EXPECT_EQ(as_float.as<float>()[3], 40003.0f);
  HostTensor flat({2, 2, 2}, DType::f32);
  for (int i = 0; i < 8; ++i) flat.as<float>()[i] = 3.f;
  write_npy(d.path / "flat.npy", flat);
  expect_error([&] { load_depth(d.path / "flat.npy"); }, {"flat.npy", "constant"});
  HostTensor neg = ramp({1, 2, 2}, -1, 1);
  write_npy(d.path / "neg.npy", neg);
  DepthOptions metric;
  metric.values = DepthValues::depth;
  expect_error([&] { load_depth(d.path / "neg.npy", metric); }, {"neg.npy", "> 0"});
  expect_error([&] { load_depth(d.path / "missing.npy"); }, {"missing.npy"});
  {
    std::ofstream f(d.path / "depth.exr");
    f << "x";
  }
  expect_error([&] { load_depth(d.path / "depth.exr"); }, {"depth.exr", ".npy"});
  // A truncated .npy.
  {
    std::vector<uint8_t> bytes = encode_npy(ramp({2, 8, 8}, 1, 1));
    std::ofstream f(d.path / "trunc.npy", std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size() - 100));
  }
  expect_error([&] { load_depth(d.path / "trunc.npy"); }, {"trunc.npy"});
  // A truncated / non-zip .npz.
  {
    std::ofstream f(d.path / "bad.npz", std::ios::binary);
    f << "PK\x03\x04 truncated";
  }
  expect_error([&] { load_depth(d.path / "bad.npz"); }, {"bad.npz"});
}

TEST(GeometryDepth, NpzKeyDepths) {
  TempDir d;
  std::vector<uint8_t> a = encode_npy(ramp({2, 3, 4}, 1, 1)), b = encode_npy(ramp({1, 1, 1}, 0, 1));
  int err = 0;
  zip_t* z = zip_open((d.path / "clip.npz").c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  ASSERT_NE(z, nullptr);
  zip_file_add(z, "other.npy", zip_source_buffer(z, b.data(), b.size(), 0), 0);
  zip_file_add(z, "depths.npy", zip_source_buffer(z, a.data(), a.size(), 0), 0);
  ASSERT_EQ(zip_close(z), 0);
  HostTensor t = read_depth_array(d.path / "clip.npz");
  ASSERT_EQ(t.shape, (Shape{2, 3, 4}));
  EXPECT_EQ(t.as<float>()[23], 24.f);
}

TEST(GeometryDepth, ImageSequenceErrors) {
  TempDir d;
  expect_error([&] { load_depth(d.path); }, {d.path.string(), "zero frames"});
  {
    std::ofstream f(d.path / "0000.png", std::ios::binary);
    f << "not a png";
  }
  expect_error([&] { load_depth(d.path); }, {"0000.png"});
  {
    std::ofstream f(d.path / "0001.exr", std::ios::binary);
    f << "x";
  }
  expect_error([&] { load_depth(d.path); }, {d.path.string(), ".png and .exr"});
}

// 16-bit grayscale PNG whose pixel (y, x) holds base + y·w + x.
void write_png16(const fs::path& p, int w, int h, uint16_t base) {
  cv::Mat img(h, w, CV_16UC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.at<uint16_t>(y, x) = uint16_t(base + y * w + x);
  ASSERT_TRUE(cv::imwrite(p.string(), img));
}

TEST(GeometryDepth, Png16Sequence) {
  TempDir d;
  write_png16(d.path / "f001.png", 5, 3, 1000);
  write_png16(d.path / "f000.png", 5, 3, 60000);
  DepthOptions mm;
  mm.values = DepthValues::depth;
  mm.metric_scale = 0.001f;
  HostTensor z = load_depth(d.path, mm);
  ASSERT_EQ(z.shape, (Shape{2, 3, 5}));
  EXPECT_FLOAT_EQ(z.as<float>()[0], 60.0f);       // f000 first: 60000 mm
  EXPECT_FLOAT_EQ(z.as<float>()[15 + 14], 1.014f);
  write_png16(d.path / "f002.png", 4, 3, 1);
  expect_error([&] { load_depth(d.path, mm); }, {"f002.png", "is 3x4 (HxW)", "f000.png is 3x5"});
}

TEST(GeometryDepth, ExrSequence) {
  setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 0);
  TempDir d;
  for (int f = 0; f < 2; ++f) {
    cv::Mat z(3, 4, CV_32FC1);
    for (int i = 0; i < 12; ++i) z.at<float>(i / 4, i % 4) = 0.5f + float(f * 12 + i);
    ASSERT_TRUE(cv::imwrite((d.path / ("d" + std::to_string(f) + ".exr")).string(), z));
  }
  DepthOptions metric;
  metric.values = DepthValues::depth;
  HostTensor z = load_depth(d.path, metric);
  ASSERT_EQ(z.shape, (Shape{2, 3, 4}));
  EXPECT_EQ(z.as<float>()[23], 23.5f);
}

TEST(GeometryDepth, Resize) {
  HostTensor z = ramp({1, 2, 2}, 1, 1);  // [[1,2],[3,4]]
  HostTensor r = resize_depth(z, 4, 4);
  ASSERT_EQ(r.shape, (Shape{1, 4, 4}));
  EXPECT_FLOAT_EQ(r.as<float>()[0], 1.f);
  EXPECT_FLOAT_EQ(r.as<float>()[1], 1.25f);   // half-pixel centres: x = 0.25
  EXPECT_FLOAT_EQ(r.as<float>()[15], 4.f);
  HostTensor same = resize_depth(z, 2, 2);
  EXPECT_EQ(same.data, z.data);
}

TEST(GeometryDepth, FitToVideoAndCentre) {
  HostTensor z = ramp({3, 4, 6}, 1, 1);
  EXPECT_EQ(centre_depth(z), 1.f + 2 * 6 + 3);  // row 2, column 3 of frame 0
  HostTensor same = fit_depth_to_video(z, 3, 4, 6, false, "d.npz");
  EXPECT_EQ(same.data, z.data);
  HostTensor two = fit_depth_to_video(z, 2, 4, 6, true, "d.npz");
  ASSERT_EQ(two.shape, (Shape{2, 4, 6}));
  EXPECT_EQ(two.as<float>()[47], z.as<float>()[47]);
  EXPECT_EQ(fit_depth_to_video(z, 3, 8, 12, false, "d.npz").shape, (Shape{3, 8, 12}));
  expect_error([&] { fit_depth_to_video(z, 2, 4, 6, false, "d.npz"); }, {"d.npz", "3 depth frames", "trim"});
  expect_error([&] { fit_depth_to_video(z, 5, 4, 6, true, "d.npz"); }, {"d.npz", "3 depth frames", "5"});
}

TEST(GeometryDepth, GrayscaleVideo) {
  test::TempDir d;
  // Disparity ramp 40..200 across columns, 3 frames, as a gray video.
  HostTensor frames({3, 3, 16, 32}, DType::f32);
  for (int f = 0; f < 3; ++f)
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 32; ++x) frames.as<float>()[((f * 3 + c) * 16 + y) * 32 + x] = (40.0f + 5.0f * x) / 127.5f - 1.0f;
  write_video(d / "depth.mp4", frames, 10);
  HostTensor raw = read_depth_array(d / "depth.mp4");
  ASSERT_EQ(raw.shape, (Shape{3, 16, 32}));
  EXPECT_NEAR(raw.as<float>()[8 * 32 + 2], 50.0f, 4.0f);   // lossy codec: a few levels
  EXPECT_NEAR(raw.as<float>()[8 * 32 + 30], 190.0f, 4.0f);
  HostTensor z = load_depth(d / "depth.mp4");  // disparity -> depth: near (bright) columns get small depth
  EXPECT_LT(z.as<float>()[8 * 32 + 30], z.as<float>()[8 * 32 + 2]);
}

}  // namespace
}  // namespace dvs
