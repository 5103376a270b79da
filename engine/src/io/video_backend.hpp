// Video files and depth images are read and written by dvs's video component (OpenCV with FFmpeg and GDAL under
// it: libdvs_video, dvs::video), not by the core library, so an application that brings its own frames links none
// of that stack. The core's read_video, write_video, read_depth_png, ... forward to the table the component
// registers when it is loaded (engine/src/video/video_component.cpp); without it .npy frame arrays still work and
// every other file gets a dvs::Error that names the component to link.
#pragma once
#include <filesystem>
#include <string>

#include "dvs/api.hpp"
#include "io/host_tensor.hpp"
#include "io/video.hpp"

namespace dvs {

struct VideoBackend {
  std::string (*library_version)();  // "OpenCV 4.6.0"
  void (*set_logs)(bool verbose);    // the libraries' own log levels (dvs/logs.hpp)
  HostTensor (*read_video)(const std::filesystem::path& path, const VideoReadOptions& options, VideoInfo* info);
  HostTensor (*read_video_rgb8)(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info);
  void (*write_video)(const std::filesystem::path& path, const HostTensor& frames, double fps);
  // One single-channel image as [H,W] f32 (kind "PNG" or "EXR"; the core has checked its declared size).
  HostTensor (*read_depth_image)(const std::filesystem::path& file, const char* kind);
};

// The registered backend, or null when the video component is not loaded.
const VideoBackend* video_backend();

// dvs::Error "<file>: <what> needs dvs's video component: ..." (the fix for an application and for a build).
[[noreturn]] void needs_video_component(const std::filesystem::path& file, const std::string& what);

namespace detail {
// Called by the video component when it is loaded; the one exported symbol outside the documented API
// (tests/install/check_exports.sh allows dvs::detail:: for it). The table must outlive the process's use of dvs.
DVS_API void set_video_backend(const VideoBackend* backend);
}  // namespace detail

}  // namespace dvs
