// Videos that cannot be used, and what the reader says about them: an empty file, a file cut short, an audio-only
// file, and a clip with fewer frames than --frames asks for. Each message names the file and the real cause (not
// "unknown container or codec") and, where frames can be read, the --frames that works.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "dvs/video.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

HostTensor grey_clip(int frames, int h, int w) {
  HostTensor t({frames, 3, h, w}, DType::f32);
  for (int64_t i = 0; i < t.numel(); ++i) t.as<float>()[i] = float(i % 97) / 97.0f - 0.5f;
  return t;
}

void truncate_to(const fs::path& p, uint64_t size) { fs::resize_file(p, size); }

// ISO base media boxes, written by hand: size (big-endian) + type + payload.
std::string box(const std::string& type, const std::string& payload) {
  const uint32_t n = uint32_t(8 + payload.size());
  std::string s = {char(n >> 24), char(n >> 16), char(n >> 8), char(n)};
  return s + type + payload;
}

// The smallest audio-only .mp4 the probe must see through: ftyp, then moov > trak > mdia > hdlr('soun'). (No
// ffmpeg program on the build machines, so the container is built here; FFmpeg refuses it either way, and the
// reader must then say why from the boxes.)
std::string audio_only_mp4() {
  const std::string hdlr = box("hdlr", std::string(8, '\0') + "soun" + std::string(12, '\0') + "SoundHandler" + '\0');
  return box("ftyp", std::string("isom") + std::string("\0\0\2\0", 4) + "isomiso2mp41") +
         box("moov", box("trak", box("mdia", hdlr)));
}

TEST(VideoProblems, EmptyFileIsNamedEmpty) {
  test::TempDir d;
  test::write_text(d / "empty.mp4", "");
  const std::string msg = test::error_of([&] { read_video(d / "empty.mp4"); });
  EXPECT_NE(msg.find("empty.mp4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("the file is empty (0 bytes)"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("unknown container"), std::string::npos) << msg;
}

TEST(VideoProblems, AudioOnlyFileHasNoVideoStream) {
  test::TempDir d;
  test::write_text(d / "song.mp4", audio_only_mp4());
  const std::string msg = test::error_of([&] { read_video_rgb8(d / "song.mp4"); });
  EXPECT_NE(msg.find("song.mp4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("holds no video stream (its tracks: audio)"), std::string::npos) << msg;
}

TEST(VideoProblems, TruncatedMp4SaysWhereItEnds) {
  test::TempDir d;
  write_video(d / "clip.mp4", grey_clip(9, 32, 32), 10);
  const uint64_t size = fs::file_size(d / "clip.mp4");
  truncate_to(d / "clip.mp4", size / 2);
  const std::string msg = test::error_of([&] { read_video(d / "clip.mp4"); });
  EXPECT_NE(msg.find("clip.mp4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("the file is truncated: it ends at byte " + std::to_string(size / 2)), std::string::npos) << msg;
}

// A file whose header says how many frames it holds (AVI) and that stops early: the frames before the cut are
// read, and asking for more names the truncation and the --frames that works.
TEST(VideoProblems, TruncatedAviNamesTheLastFrameAndTheFramesThatWork) {
  test::TempDir d;
  const fs::path avi = d / "cut.avi";
  {
    cv::VideoWriter w(avi.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10, cv::Size(64, 48));
    ASSERT_TRUE(w.isOpened());
    for (int f = 0; f < 21; ++f) w.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(f * 10, 255 - f * 10, 128)));
  }
  VideoInfo whole;
  ASSERT_EQ(read_video(avi, {}, &whole).shape[0], 21);
  truncate_to(avi, fs::file_size(avi) * 6 / 10);
  VideoReadOptions o;
  o.max_frames = 21;
  const std::string msg = test::error_of([&] { read_video(avi, o); });
  EXPECT_NE(msg.find("cut.avi: holds "), std::string::npos) << msg;
  EXPECT_NE(msg.find("fewer than --frames 21 (the file is truncated or damaged: its header announces 21 frames"),
            std::string::npos)
      << msg;
  // The count it gives is one that works.
  const size_t at = msg.find("; use --frames ");
  ASSERT_NE(at, std::string::npos) << msg;
  o.max_frames = std::stoi(msg.substr(at + 15));
  EXPECT_GE(o.max_frames, 1);
  EXPECT_EQ((o.max_frames - 1) % 4, 0);
  EXPECT_EQ(read_video(avi, o).shape[0], o.max_frames);
}

TEST(VideoProblems, FewerFramesThanAskedIsAnErrorWithTheCountThatWorks) {
  test::TempDir d;
  write_video(d / "three.mp4", grey_clip(3, 32, 32), 10);
  VideoReadOptions o;
  o.max_frames = 9;
  test::expect_error([&] { read_video(d / "three.mp4", o); },
                     {"three.mp4: holds 3 frames, fewer than --frames 9; use --frames 1 (the largest 4k+1",
                      "any count up to 3"});
  test::expect_error([&] { read_video_rgb8(d / "three.mp4", 9); }, {"three.mp4: holds 3 frames, fewer than --frames 9"});
  o.max_frames = 3;
  EXPECT_EQ(read_video(d / "three.mp4", o).shape[0], 3);
  // Frame arrays follow the same rule.
  write_npy(d / "three.npy", grey_clip(3, 8, 8));
  o.max_frames = 5;
  test::expect_error([&] { read_video(d / "three.npy", o); }, {"three.npy: holds 3 frames, fewer than --frames 5"});
}

// The library's readers (dvs/video.hpp) name frames past the end in their call's terms, not the dvs program's
// --frames, which their caller never gave (issue 34 §3: the preview's --frame-index 60 on a 49-frame clip).
TEST(VideoProblems, LibraryReadersNameTheFramesAskedForNotTheProgramsOptions) {
  test::TempDir d;
  write_video(d / "three.mp4", grey_clip(3, 32, 32), 10);
  const std::string one = test::error_of([&] { read_video_frames(d / "three.mp4", 7, 1, 32, 32); });
  EXPECT_NE(one.find("three.mp4: frame 7 asked for, but the video holds 3 frames (frames 0..2)"), std::string::npos) << one;
  const std::string some = test::error_of([&] { read_video_frames(d / "three.mp4", 2, 4, 32, 32); });
  EXPECT_NE(some.find("three.mp4: frames 2..5 asked for, but the video holds 3 frames"), std::string::npos) << some;
  const std::string depth = test::error_of([&] { read_video_frames_for_depth(d / "three.mp4", 9); });
  EXPECT_NE(depth.find("three.mp4: frames 0..8 asked for, but the video holds 3 frames"), std::string::npos) << depth;
  for (const std::string& m : {one, some, depth}) EXPECT_EQ(m.find("--frames"), std::string::npos) << m;
  EXPECT_EQ(read_video_frames(d / "three.mp4", 2, 1, 32, 32).count, 1);  // the last frame is there
}

// `dvs render --frames 9` on a 3-frame clip: refused before anything is written.
TEST(VideoProblems, RenderRefusesMoreFramesThanTheClipHas) {
  test::TempDir d;
  write_video(d / "three.mp4", grey_clip(3, 32, 32), 10);
  HostTensor depth({3, 32, 32}, DType::f32);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = 1.0f + float(i % 7);
  write_npy(d / "depth.npy", depth);
  const auto r = test::run_command(test::program("dvs") + " render --video " + (d / "three.mp4").string() + " --depth " +
                                   (d / "depth.npy").string() + " --size 32x32 --frames 9 --out " + (d / "out").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("three.mp4: holds 3 frames, fewer than --frames 9"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(d / "out" / "render.mp4"));
}

}  // namespace
}  // namespace dvs
