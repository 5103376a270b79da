#include "io/video_backend.hpp"

#include <atomic>

#include "dvs/error.hpp"
#include "io/third_party_logs.hpp"

namespace dvs {
namespace {

std::atomic<const VideoBackend*> g_backend{nullptr};

}  // namespace

const VideoBackend* video_backend() { return g_backend.load(std::memory_order_acquire); }

void detail::set_video_backend(const VideoBackend* backend) {
  g_backend.store(backend, std::memory_order_release);
  // A log level the application chose before the component was loaded applies to it too.
  if (backend && third_party_logs_chosen()) backend->set_logs(third_party_logs_verbose());
}

void needs_video_component(const std::filesystem::path& file, const std::string& what) {
  throw Error(file.string() + ": " + what + " needs dvs's video component (OpenCV with FFmpeg): link dvs::video "
              "(find_package(dvs COMPONENTS video), or pkg-config dvs-video) and call dvs::enable_video_files(), or give "
              "it as .npy (frames: f32 [F,3,H,W] in [-1,1] or u8 [F,H,W,3]; depth: .npy/.npz); a dvs built with "
              "-DDVS_VIDEO_IO=OFF has no video component");
}

}  // namespace dvs
