// A clip handed over in memory (dvs/clip_run.hpp) made into what stages 1–2 of a run make from files: frames in
// [−1,1] by the video reader's level rule (io/pixel_levels.hpp), depth converted as a depth file is (io/depth.hpp),
// the camera path from poses or from the named trajectory with the radius of the clip's centre depth, the job's
// intrinsics, the render and its visibility check (pipeline/render_stage.hpp). Given the frames a video decode
// gives and the depth a depth file holds, the RenderedInput equals render_stage's.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dvs/render.hpp"
#include "io/host_tensor.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/stage_tracker.hpp"
#include "vk/context.hpp"

namespace dvs {

// The clip, converted and checked (clip_input): everything the render needs.
struct ClipInput {
  HostTensor rgb;                   // [F,3,H,W] in [−1,1]
  HostTensor depth;                 // [F,H,W] metric depth (after the disparity conversion)
  geometry::Trajectory trajectory;  // F world-to-camera transforms
};

// u8 [F,H,W,3] RGB levels → [F,3,H,W] in [−1,1], exactly as the video reader converts decoded pixels.
HostTensor frames_from_levels(const uint8_t* rgb, int64_t frames, int64_t height, int64_t width);

// Depth values [F,H,W] (disparity, or metric depth with job.metric_depth) converted and checked as a depth file is
// (non-finite values, a constant or negative disparity, non-positive depth: errors naming `depth_name`), and the
// camera path: `poses` (F transforms) when given, else job.trajectory with the official radius of the converted
// depth's centre, as `dvs render` builds it.
ClipInput clip_input(const RenderJob& job, HostTensor rgb, const HostTensor& depth_values, const std::string& depth_name,
                     const std::optional<std::vector<glm::dmat4>>& poses);

// Stage "render": the clip's splat render and mask, checked for visibility as render_stage checks them.
RenderedInput render_clip_input(vk::Context& ctx, const RenderJob& job, const ClipInput& clip, StageTracker& stages);

// The caches' key parts naming a clip in memory, in the place of the files' fingerprints and the trajectory:
// fingerprints of the frames' bytes as given (with their element type), of the depth values as given, and of the
// poses at full precision (or the trajectory's name when the path is named).
std::vector<std::string> clip_input_key(const void* frames, size_t frame_bytes, const std::string& frames_type,
                                        const HostTensor& depth_values, const std::optional<std::vector<glm::dmat4>>& poses,
                                        const std::string& trajectory);

// Refuses (ErrorKind::invalid_argument) a clip the model cannot take: F = 4k+1 frames ("8 is not 4k+1", named
// `frames_name`), H and W positive multiples of 8 (named `size_name`); each message says what to give instead.
void check_clip_size(int64_t frames, int64_t height, int64_t width, const std::string& frames_name,
                     const std::string& size_name);

// The sampled latent's shape [Fl,C,h,w] for a clip of frames × height × width, from the model's VAE config
// (Fl = (F−1)/temporal_compression + 1, C = latent_channels, h×w = H×W / spatial ratio); a size check_clip_size
// refuses is refused first.
std::vector<int64_t> clip_latent_shape(const std::filesystem::path& model, int64_t frames, int64_t height, int64_t width);

}  // namespace dvs
