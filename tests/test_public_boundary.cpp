// The public C++ calls on files (dvs::read_video_frames, render_novel_view, estimate_depth, run_pipeline, ...) let
// only a dvs::Error out (issue 34 §2.9): what the work below them throws otherwise (OpenCV's cv::Exception,
// std::bad_alloc, std::filesystem_error) becomes an Error naming the call, out_of_memory for host memory, internal
// for the rest (io/public_call.hpp).
#include <gtest/gtest.h>

#include <climits>
#include <filesystem>
#include <string>
#include <typeinfo>

#include "dvs/error.hpp"
#include "dvs/video.hpp"
#include "io/host_tensor.hpp"
#include "io/public_call.hpp"
#include "io/video.hpp"
#include "support/files.hpp"

namespace dvs {
namespace {

// What a call threw: "dvs::Error" with its kind and message, or the other exception's type.
struct Thrown {
  bool dvs_error = false;
  ErrorKind kind = ErrorKind::internal;
  std::string what;
};
template <class Call>
Thrown thrown_by(Call&& call) {
  try {
    call();
  } catch (const Error& e) {
    return {true, e.kind(), e.what()};
  } catch (const std::exception& e) {
    return {false, ErrorKind::internal, std::string(typeid(e).name()) + ": " + e.what()};
  } catch (...) {
    return {false, ErrorKind::internal, "an exception that is not a std::exception"};
  }
  return {false, ErrorKind::internal, "nothing thrown"};
}

// The boundary itself: each kind of exception, as the calls' bodies may throw them.
TEST(PublicBoundary, OnlyADvsErrorLeavesACall) {
  const Thrown kept = thrown_by([] { public_call("dvs::x", []() -> int { throw Error("bad file", ErrorKind::input); }); });
  EXPECT_TRUE(kept.dvs_error);
  EXPECT_EQ(kept.kind, ErrorKind::input);
  EXPECT_EQ(kept.what, "bad file") << "a dvs::Error passes unchanged";
  const Thrown memory = thrown_by([] { public_call("dvs::x", []() -> int { throw std::bad_alloc(); }); });
  EXPECT_TRUE(memory.dvs_error);
  EXPECT_EQ(memory.kind, ErrorKind::out_of_memory);
  EXPECT_EQ(memory.what.rfind("dvs::x: out of host memory", 0), 0u) << memory.what;
  const Thrown fs_error = thrown_by([] {
    public_call("dvs::x", []() -> int {
      throw std::filesystem::filesystem_error("cannot", std::make_error_code(std::errc::io_error));
    });
  });
  EXPECT_TRUE(fs_error.dvs_error);
  EXPECT_EQ(fs_error.kind, ErrorKind::internal);
  EXPECT_EQ(fs_error.what.rfind("dvs::x: internal error: ", 0), 0u) << fs_error.what;
  const Thrown other = thrown_by([] { public_call("dvs::x", []() -> int { throw 7; }); });
  EXPECT_TRUE(other.dvs_error);
  EXPECT_EQ(other.kind, ErrorKind::internal);
}

// Through a production call: frames brought to a size no host can hold (2^20 x 2^20 x 3 bytes a frame) threw
// OpenCV's exception out of dvs::read_video_frames.
TEST(PublicBoundary, AVideoReadAtAnImpossibleSizeIsADvsError) {
  test::TempDir dir;
  HostTensor clip({3, 3, 16, 16}, DType::f32);
  for (int64_t i = 0; i < clip.numel(); ++i) clip.as<float>()[i] = float(i % 31) / 31.0f - 0.5f;
  write_video(dir.path / "clip.mp4", clip, 10);
  enable_video_files();
  const Thrown huge = thrown_by([&] { read_video_frames(dir.path / "clip.mp4", 0, 1, 1 << 20, 1 << 20); });
  EXPECT_TRUE(huge.dvs_error) << huge.what;
  EXPECT_NE(huge.what.find("dvs::read_video_frames"), std::string::npos) << huge.what;
}

}  // namespace
}  // namespace dvs
