// Depth that does not fit the video is never used silently: another aspect ratio is an error unless
// --depth-fit says how to map it, image frames are taken in natural order, a colour video is refused; and
// the common layouts of depth tools are read: u16 .npy, [N,H,W,1], FILE.npz:KEY.
#include <gtest/gtest.h>

#include <zip.h>

#include <cstring>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "dvs/error.hpp"
#include "io/depth.hpp"
#include "io/depth_images.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// [N,H,W] f32 with value(f, y, x).
HostTensor make_depth(int n, int h, int w, const std::function<float(int, int, int)>& value) {
  HostTensor t({n, h, w}, DType::f32);
  for (int f = 0; f < n; ++f)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) t.as<float>()[(size_t(f) * h + y) * w + x] = value(f, y, x);
  return t;
}

TEST(IoDepthSanity, NaturalOrderOfFrameNames) {
  EXPECT_TRUE(natural_less("d_2.png", "d_10.png"));
  EXPECT_FALSE(natural_less("d_10.png", "d_2.png"));
  EXPECT_TRUE(natural_less("d_9.png", "d_10.png"));
  EXPECT_TRUE(natural_less("a_100", "b_2"));         // text before the number still decides
  EXPECT_TRUE(natural_less("d_007.png", "d_8.png"));  // zero-padded names keep their order
  EXPECT_TRUE(natural_less("d_2.png", "d_02.png"));   // equal numbers: fewer leading zeros first
  EXPECT_FALSE(natural_less("d_2.png", "d_2.png"));

  // A folder d_0 … d_16 of 16-bit PNGs whose every pixel holds its frame number.
  test::TempDir d;
  for (int i = 0; i <= 16; ++i) {
    cv::Mat m(6, 8, CV_16UC1, cv::Scalar(1000 + i));
    ASSERT_TRUE(cv::imwrite((d / ("d_" + std::to_string(i) + ".png")).string(), m));
  }
  const HostTensor t = read_depth_image_sequence(d.path);
  ASSERT_EQ(t.shape, (Shape{17, 6, 8}));
  for (int i = 0; i <= 16; ++i) EXPECT_EQ(t.as<float>()[size_t(i) * 48 + 5], float(1000 + i)) << "frame " << i;
}

TEST(IoDepthSanity, ColourDepthVideoIsRefusedGrayIsRead) {
  test::TempDir d;
  const int F = 3, H = 32, W = 48;
  HostTensor gray({F, 3, H, W}, DType::f32), colour({F, 3, H, W}, DType::f32);
  for (int f = 0; f < F; ++f)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const float g = -1.0f + 2.0f * float(x) / float(W - 1);  // a ramp, R = G = B
        for (int c = 0; c < 3; ++c) {
          gray.as<float>()[((size_t(f) * 3 + c) * H + y) * W + x] = g;
          // A "jet" colour map of the same ramp: red rises, blue falls.
          colour.as<float>()[((size_t(f) * 3 + c) * H + y) * W + x] = c == 0 ? g : c == 1 ? 0.0f : -g;
        }
      }
  write_video(d / "gray.mp4", gray, 10);
  write_video(d / "colour.mp4", colour, 10);
  const HostTensor z = read_depth_array(d / "gray.mp4");
  EXPECT_EQ(z.shape, (Shape{F, H, W}));
  EXPECT_NEAR(z.as<float>()[W - 1], 255.0f, 6.0f);
  const std::string e = error_of([&] { read_depth_array(d / "colour.mp4"); });
  EXPECT_NE(e.find("colour.mp4: frame 0 is in colour"), std::string::npos) << e;
}

// A .npy of u16 [N,H,W], written byte by byte as numpy does.
void write_u16_npy(const fs::path& p, int n, int h, int w) {
  std::string header = "{'descr': '<u2', 'fortran_order': False, 'shape': (" + std::to_string(n) + ", " +
                       std::to_string(h) + ", " + std::to_string(w) + "), }";
  while ((10 + header.size() + 1) % 64) header += ' ';
  header += '\n';
  std::string bytes = std::string("\x93NUMPY\x01\x00", 8);
  bytes += char(header.size() & 0xff);
  bytes += char(header.size() >> 8);
  bytes += header;
  for (int i = 0; i < n * h * w; ++i) {
    const uint16_t v = uint16_t(60000 + i);  // above 32767: a signed read would go negative
    bytes.append(reinterpret_cast<const char*>(&v), 2);
  }
  test::write_text(p, bytes);
}

TEST(IoDepthSanity, U16NpyAndChannelLastAndNpzKeyAreRead) {
  test::TempDir d;
  write_u16_npy(d / "u16.npy", 2, 3, 4);
  const HostTensor u = read_depth_array(d / "u16.npy");
  ASSERT_EQ(u.shape, (Shape{2, 3, 4}));
  ASSERT_EQ(u.dtype, DType::f32);
  for (int i = 0; i < 24; ++i) EXPECT_EQ(u.as<float>()[i], float(60000 + i));

  HostTensor nhw1 = make_depth(2, 3, 4, [](int f, int y, int x) { return float(100 * f + 10 * y + x + 1); });
  nhw1.shape = {2, 3, 4, 1};
  write_npy(d / "nhw1.npy", nhw1);
  const HostTensor c = read_depth_array(d / "nhw1.npy");
  ASSERT_EQ(c.shape, (Shape{2, 3, 4}));
  EXPECT_EQ(c.as<float>()[1 * 12 + 2 * 4 + 3], 124.0f);

  // An .npz with two arrays and no 'depths': FILE.npz:KEY picks one.
  const HostTensor a = make_depth(1, 2, 2, [](int, int, int) { return 1.0f; });
  const HostTensor b = make_depth(1, 2, 2, [](int, int, int) { return 2.0f; });
  const auto ea = encode_npy(a), eb = encode_npy(b);
  int err = 0;
  zip_t* z = zip_open((d / "two.npz").c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  ASSERT_NE(z, nullptr);
  zip_file_add(z, "disp.npy", zip_source_buffer(z, ea.data(), ea.size(), 0), 0);
  zip_file_add(z, "depth.npy", zip_source_buffer(z, eb.data(), eb.size(), 0), 0);
  ASSERT_EQ(zip_close(z), 0);
  EXPECT_EQ(read_depth_array((d / "two.npz").string() + ":depth").as<float>()[0], 2.0f);
  EXPECT_EQ(read_depth_array((d / "two.npz").string() + ":disp").as<float>()[0], 1.0f);
  EXPECT_TRUE(depth_source_exists((d / "two.npz").string() + ":depth"));
  EXPECT_FALSE(depth_source_exists((d / "none.npz").string() + ":depth"));
  const std::string missing = error_of([&] { read_depth_array((d / "two.npz").string() + ":nope"); });
  EXPECT_NE(missing.find("has no array 'nope'"), std::string::npos) << missing;
  EXPECT_NE(missing.find("disp.npy"), std::string::npos) << missing;
  const std::string ambiguous = error_of([&] { read_depth_array(d / "two.npz"); });
  EXPECT_NE(ambiguous.find(":KEY"), std::string::npos) << ambiguous;
}

// Depth whose value is its column: where a mapped pixel samples the depth is read off its value.
TEST(IoDepthSanity, AspectMismatchNeedsDepthFitAndCropFollowsTheVideo) {
  const HostTensor wide = make_depth(1, 40, 80, [](int, int, int x) { return float(x); });
  const VideoFrameGeometry square{40, 40, 40, 40, ResizeMode::crop};  // a 40x40 video used as it is
  const std::string e = error_of([&] { map_depth_to_video(wide, 1, square, DepthFit::error, false, "d.npy"); });
  EXPECT_NE(e.find("d.npy: the depth frames are 40x80 (HxW) but the video's are 40x40"), std::string::npos) << e;
  EXPECT_NE(e.find("RenderJob::depth_fit stretch"), std::string::npos) << e;  // the field: a library call
  // crop: the depth's centre columns 20..59; stretch: column 2x + 0.5 (half-pixel centres).
  const HostTensor crop = map_depth_to_video(wide, 1, square, DepthFit::crop, false, "d.npy");
  const HostTensor stretch = map_depth_to_video(wide, 1, square, DepthFit::stretch, false, "d.npy");
  ASSERT_EQ(crop.shape, (Shape{1, 40, 40}));
  for (int x : {0, 7, 39}) {
    EXPECT_FLOAT_EQ(crop.as<float>()[5 * 40 + x], float(20 + x)) << x;
    EXPECT_FLOAT_EQ(stretch.as<float>()[5 * 40 + x], std::min(2.0f * float(x) + 0.5f, 79.0f)) << x;
  }
  // Orientation: portrait depth for a landscape video is named as such.
  const HostTensor portrait = make_depth(1, 80, 40, [](int, int, int x) { return float(x); });
  const VideoFrameGeometry landscape{40, 80, 40, 80, ResizeMode::crop};
  const std::string o = error_of([&] { map_depth_to_video(portrait, 1, landscape, DepthFit::error, false, "p.npy"); });
  EXPECT_NE(o.find("aspect ratio and orientation"), std::string::npos) << o;

  // Depth of the video's own shape under --resize crop to a square working size: the video keeps its
  // centre columns 20..59, and so must the depth (it used to be squashed: 2x + 0.5).
  const VideoFrameGeometry cropped{40, 80, 40, 40, ResizeMode::crop};
  const HostTensor aligned = map_depth_to_video(wide, 1, cropped, DepthFit::error, false, "d.npy");
  for (int x : {0, 13, 39}) EXPECT_FLOAT_EQ(aligned.as<float>()[3 * 40 + x], float(20 + x)) << x;
  // Under --resize squash the whole frame is used.
  const VideoFrameGeometry squashed{40, 80, 40, 40, ResizeMode::squash};
  const HostTensor all = map_depth_to_video(wide, 1, squashed, DepthFit::error, false, "d.npy");
  EXPECT_FLOAT_EQ(all.as<float>()[3 * 40 + 10], 20.5f);
  // Within the 2% tolerance (a depth model's rounded size) the aspect ratios count as equal.
  const HostTensor near = make_depth(1, 40, 81, [](int, int, int x) { return float(x); });
  EXPECT_NO_THROW(map_depth_to_video(near, 1, VideoFrameGeometry{40, 80, 40, 80, ResizeMode::crop}, DepthFit::error,
                                     false, "n.npy"));
  EXPECT_EQ(parse_depth_fit("crop"), DepthFit::crop);
  EXPECT_THROW(parse_depth_fit("squash"), Error);
}

TEST(IoDepthSanity, DvsRenderRefusesMismatchedDepthUnlessTold) {
  test::TempDir d;
  HostTensor rgb({3, 3, 48, 64}, DType::f32);
  for (int64_t i = 0; i < rgb.numel(); ++i) rgb.as<float>()[i] = float(i % 7) / 7.0f - 0.5f;
  write_video(d / "v.mp4", rgb, 10);
  write_npy(d / "portrait.npy", make_depth(3, 64, 48, [](int, int y, int x) { return 2.0f + 0.01f * float(x + y); }));
  const std::string base = test::program("dvs") + " render --video " + (d / "v.mp4").string() + " --depth " +
                           (d / "portrait.npy").string() + " --metric-depth --size 48x64 --frames 3 --no-glb --out ";
  const auto refused = test::run_command(base + (d / "a").string());
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find("--depth-fit"), std::string::npos) << refused.output;
  EXPECT_FALSE(fs::exists(d / "a" / "render.mp4"));
  const auto stretched = test::run_command(base + (d / "b").string() + " --depth-fit stretch");
  EXPECT_EQ(stretched.exit_code, 0) << stretched.output;
  // Sizes are printed as H×W, like --size (the 48×64 video is landscape).
  EXPECT_NE(stretched.output.find("rendered 3 frames at 48x64 (HxW)"), std::string::npos) << stretched.output;
  EXPECT_EQ(test::run_command(base + (d / "c").string() + " --depth-fit sideways").exit_code, 2);
}

}  // namespace
}  // namespace dvs
