#include "pipeline/clip_input.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "dvs/error.hpp"
#include "geometry/splat.hpp"
#include "geometry/trajectory.hpp"
#include "io/depth.hpp"
#include "io/json_file.hpp"
#include "io/library_log.hpp"
#include "io/pixel_levels.hpp"
#include "pipeline/inversion_cache.hpp"
#include "io/option_names.hpp"
#include "spec/cogvideox_config.hpp"

namespace dvs {

HostTensor frames_from_levels(const uint8_t* rgb, int64_t frames, int64_t height, int64_t width) {
  const int64_t plane = height * width;
  HostTensor out({frames, 3, height, width}, DType::f32);
  float* dst = out.as<float>();
  for (int64_t f = 0; f < frames; ++f)
    for (int64_t i = 0; i < plane; ++i)
      for (int64_t c = 0; c < 3; ++c) dst[(f * 3 + c) * plane + i] = level_to_unit(rgb[(f * plane + i) * 3 + c]);
  return out;
}

ClipInput clip_input(const RenderJob& job, HostTensor rgb, const HostTensor& depth_values, const std::string& depth_name,
                     const std::optional<std::vector<glm::dmat4>>& poses) {
  ClipInput c;
  const int F = int(rgb.shape[0]);
  c.rgb = std::move(rgb);
  DepthOptions dopt;
  dopt.values = job.metric_depth ? DepthValues::depth : DepthValues::disparity;
  c.depth = depth_from_array(depth_values, depth_name, dopt);  // the depth file's conversion and checks
  if (poses) {
    c.trajectory.transforms = *poses;
    c.trajectory.description = std::to_string(F) + " poses given in memory";
  } else {
    try {
      c.trajectory = geometry::load_trajectory(job.trajectory, F, geometry::official_radius(centre_depth(c.depth)));
    } catch (const Error& e) {
      throw Error(option_name("RunOptions::render.trajectory") + ": " + std::string(e.what()), e.kind());
    }
  }
  return c;
}

RenderedInput render_clip_input(vk::Context& ctx, const RenderJob& job, const ClipInput& clip, StageTracker& stages) {
  stages.begin("render", "rendering the clip");
  auto say = [&](const std::string& s) { stages.say(0, 0, s); };
  if (auto p = render_limits_problem(job, ctx.caps())) throw Error(*p);
  RenderedInput r;
  r.rgb = clip.rgb;
  r.depth = clip.depth;
  r.trajectory = clip.trajectory;
  r.K = job_intrinsics(job);
  say("trajectory " + r.trajectory.description);
  for (const auto& w : r.trajectory.warnings) log_warning(w);
  geometry::SplatOptions sopt;
  sopt.mode = job.hard_points ? geometry::SplatMode::hard_point : geometry::SplatMode::soft_bilinear;
  say("rendering on " + ctx.caps().name);
  geometry::RenderedClip rendered = geometry::render_clip(ctx, r.rgb, r.depth, r.trajectory, r.K, sopt);
  r.render = std::move(rendered.render);
  r.mask = std::move(rendered.mask);
  check_visibility(r.mask, job, geometry::official_radius(centre_depth(r.depth)), say,
                   "the mask (ClipResultViews::mask, dvs_run_pipeline_clip's mask)");
  stages.end();
  return r;
}

std::vector<std::string> clip_input_key(const void* frames, size_t frame_bytes, const std::string& frames_type,
                                        const HostTensor& depth_values, const std::optional<std::vector<glm::dmat4>>& poses,
                                        const std::string& trajectory) {
  std::vector<std::string> parts{"clip frames " + frames_type + " " + InversionCache::bytes_key(frames, frame_bytes),
                                 "clip depth " + InversionCache::bytes_key(depth_values.data.data(), depth_values.bytes())};
  if (!poses) {
    parts.push_back(trajectory);
    return parts;
  }
  std::string text = "poses";
  for (const glm::dmat4& T : *poses)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) {
        char buf[32];
        std::snprintf(buf, sizeof buf, " %.17g", T[c][r]);  // glm is column-major; row-major as run.json lists them
        text += buf;
      }
  parts.push_back(InversionCache::key({text}));
  return parts;
}

void check_clip_size(int64_t frames, int64_t height, int64_t width, const std::string& frames_name,
                     const std::string& size_name) {
  if (frames < 1 || (frames - 1) % 4 != 0) {
    const int64_t below = std::max<int64_t>(1, (frames - 1) / 4 * 4 + 1);
    throw Error(frames_name + ": " + std::to_string(frames) + " frames; " + std::to_string(frames) +
                    " is not 4k+1, the counts the model takes (the VAE compresses time by 4 after the first frame): "
                    "give " + (frames > 1 ? std::to_string(below) + " or " : std::string()) + std::to_string(below + 4),
                ErrorKind::invalid_argument);
  }
  if (height < 8 || width < 8 || height % 8 || width % 8) {
    auto down = [](int64_t v) { return std::to_string(std::max<int64_t>(8, v / 8 * 8)); };
    throw Error(size_name + ": " + std::to_string(height) + "x" + std::to_string(width) +
                    " (HxW); height and width must be positive multiples of 8 (the VAE works on 8x8 pixel cells): "
                    "resize the frames, e.g. to " + down(height) + "x" + down(width),
                ErrorKind::invalid_argument);
  }
}

std::vector<int64_t> clip_latent_shape(const std::filesystem::path& model, int64_t frames, int64_t height, int64_t width) {
  check_clip_size(frames, height, width, "the clip's frame count", "the clip's size");
  const VaeConfig v = VaeConfig::from_json(
      read_json_file(model / "vae" / "config.json", "give the CogVideoX-5b-I2V folder (RunOptions::model)"));
  const int64_t r = v.spatial_ratio();
  return {(frames - 1) / v.temporal_compression_ratio + 1, v.latent_channels, height / r, width / r};
}

}  // namespace dvs
