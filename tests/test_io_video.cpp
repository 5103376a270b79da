// Video files: encode/decode round trips, working-size resizing (crop and squash), side-by-side
// stacking, and errors for unreadable inputs.
#include <gtest/gtest.h>

#include <cmath>

#include "dvs/error.hpp"
#include "io/video.hpp"
#include "support/files.hpp"

namespace dvs {
namespace {

using test::TempDir;

// A smooth moving gradient, [F,3,H,W] in [−1,1]; smooth so that lossy codecs keep it within a few levels.
HostTensor gradient_clip(int F, int H, int W) {
  HostTensor t({F, 3, H, W}, DType::f32);
  float* p = t.as<float>();
  for (int f = 0; f < F; ++f)
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          *p++ = 0.8f * std::sin(0.05f * float(x + 3 * f) + 0.07f * float(y) + float(c));
  return t;
}

double mean_abs_diff(const HostTensor& a, const HostTensor& b) {
  double s = 0;
  for (int64_t i = 0; i < a.numel(); ++i) s += std::fabs(a.as<float>()[i] - b.as<float>()[i]);
  return s / double(a.numel());
}

TEST(IoVideo, WriteAndReadBack) {
  TempDir d;
  HostTensor clip = gradient_clip(9, 48, 64);
  write_video(d / "clip.mp4", clip, 24.0);
  ASSERT_TRUE(std::filesystem::exists(d / "clip.mp4"));
  for (auto& e : std::filesystem::directory_iterator(d.path))  // no temporary left behind
    EXPECT_EQ(e.path().filename(), "clip.mp4");
  VideoInfo info;
  HostTensor back = read_video(d / "clip.mp4", {}, &info);
  EXPECT_EQ(back.shape, clip.shape);
  EXPECT_EQ(info.frames, 9);
  EXPECT_EQ(info.width, 64);
  EXPECT_EQ(info.height, 48);
  EXPECT_NEAR(info.fps, 24.0, 1e-3);
  EXPECT_LT(mean_abs_diff(back, clip), 0.05);  // lossy codec, 8-bit
  VideoReadOptions first;
  first.max_frames = 4;
  EXPECT_EQ(read_video(d / "clip.mp4", first).shape[0], 4);
}

TEST(IoVideo, ResizeCropAndSquash) {
  TempDir d;
  // 128x48 (wide): crop to 48x48 keeps the centre columns; squash keeps everything.
  HostTensor clip({1, 3, 48, 128}, DType::f32);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 128; ++x) clip.as<float>()[(c * 48 + y) * 128 + x] = (x < 40 || x >= 88) ? -0.8f : 0.8f;
  write_video(d / "wide.mp4", clip, 30);
  VideoReadOptions crop;
  crop.height = 48;
  crop.width = 48;
  HostTensor c = read_video(d / "wide.mp4", crop);
  ASSERT_EQ(c.shape, (Shape{1, 3, 48, 48}));
  EXPECT_GT(c.as<float>()[24 * 48 + 24], 0.5f);  // centre is bright
  EXPECT_GT(c.as<float>()[24 * 48 + 2], 0.5f);   // the dark sides were cropped away
  VideoReadOptions squash = crop;
  squash.resize = ResizeMode::squash;
  HostTensor s = read_video(d / "wide.mp4", squash);
  EXPECT_LT(s.as<float>()[24 * 48 + 2], -0.5f);  // sides kept
}

TEST(IoVideo, BadInputsNameTheFile) {
  TempDir d;
  try {
    read_video(d / "missing.mp4");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.mp4"), std::string::npos);
  }
  test::write_text(d / "fake.mp4", "this is not a video");
  try {
    read_video(d / "fake.mp4");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("fake.mp4"), std::string::npos);
  }
  EXPECT_THROW(write_video(d / "no_such_folder" / "x.mp4", gradient_clip(1, 16, 16), 30), Error);
}

TEST(IoVideo, HstackPlacesInputsSideBySide) {
  HostTensor a({2, 3, 4, 5}, DType::f32), b({2, 3, 4, 3}, DType::f32);
  for (int64_t i = 0; i < a.numel(); ++i) a.as<float>()[i] = 1;
  for (int64_t i = 0; i < b.numel(); ++i) b.as<float>()[i] = 2;
  HostTensor s = hstack_videos({&a, &b});
  ASSERT_EQ(s.shape, (Shape{2, 3, 4, 8}));
  EXPECT_EQ(s.as<float>()[4], 1.0f);
  EXPECT_EQ(s.as<float>()[5], 2.0f);
}

}  // namespace
}  // namespace dvs
