// dvs/clip_run.hpp: a whole run on a clip in memory, on the application's context. The views and options are checked
// here, before any work (each error names the view or option and what to do); the stages are run_pipeline's own
// (pipeline/run_stages.hpp) with ends that take the clip from memory (pipeline/clip_input.hpp) and put the results
// into the application's views.
#include "dvs/clip_run.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>

#include "dvs/error.hpp"
#include "io/pixel_levels.hpp"
#include "pipeline/clip_input.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/preflight.hpp"
#include "pipeline/run_stages.hpp"

namespace dvs {
namespace {

[[noreturn]] void refuse(const std::string& what) { throw Error("dvs::run_pipeline on a clip: " + what); }

std::string dims(const std::vector<int64_t>& s) {
  std::string t;
  for (size_t i = 0; i < s.size(); ++i) t += (i ? "," : "") + std::to_string(s[i]);
  return "[" + t + "]";
}

// Where a frames-like view's pixels are: u8 [F,H,W,3] or f32 [F,3,H,W].
bool rgb8(const HostView& v, int64_t F, int64_t H, int64_t W) {
  return v.type == ElementType::u8 && v.shape == std::vector<int64_t>{F, H, W, 3};
}
bool planar(const HostView& v, int64_t F, int64_t H, int64_t W) {
  return v.type == ElementType::f32 && v.shape == std::vector<int64_t>{F, 3, H, W};
}

void check_result_view(const char* name, const HostView& v, int64_t F, int64_t H, int64_t W, bool required) {
  if (!v.data) {
    if (required) refuse(std::string(name) + ": the view's data pointer is null (give memory for the new view)");
    return;
  }
  if (!rgb8(v, F, H, W) && !planar(v, F, H, W))
    refuse(std::string(name) + ": expected u8 " + dims({F, H, W, 3}) + " or f32 " + dims({F, 3, H, W}) +
           " (the clip's F,H,W), got " + v.describe());
}

void check_f32_view(const char* name, const HostView& v, const std::vector<int64_t>& shape, const std::string& why) {
  if (v.data && (v.type != ElementType::f32 || v.shape != shape))
    refuse(std::string(name) + ": expected f32 " + dims(shape) + " (" + why + "), got " + v.describe());
}

// The frames' F, H, W; the frames and depth views checked.
struct ClipSize {
  int64_t F = 0, H = 0, W = 0;
};

ClipSize check_clip(const ClipView& clip) {
  const auto& s = clip.frames.shape;
  ClipSize z;
  if (clip.frames.type == ElementType::u8 && s.size() == 4 && s[3] == 3) z = {s[0], s[1], s[2]};
  else if (clip.frames.type == ElementType::f32 && s.size() == 4 && s[1] == 3) z = {s[0], s[2], s[3]};
  else refuse("ClipView::frames: expected u8 [F,H,W,3] RGB or f32 [F,3,H,W] in [-1,1], got " + clip.frames.describe());
  if (!clip.frames.data) refuse("ClipView::frames: the view's data pointer is null (give the frames' memory)");
  if (z.F < 1 || (z.F - 1) % 4 != 0)
    refuse("ClipView::frames: " + std::to_string(z.F) + " frames; the model takes 4k+1 (e.g. " +
           std::to_string(std::max<int64_t>(1, (z.F - 1) / 4 * 4 + 1)) + "): give that many");
  if (z.H < 8 || z.W < 8 || z.H % 8 || z.W % 8)
    refuse("ClipView::frames: " + std::to_string(z.H) + "x" + std::to_string(z.W) +
           " (HxW); height and width must be positive multiples of 8 (the VAE works on 8x8 pixel cells): resize the frames");
  if (clip.depth.type != ElementType::f32 || clip.depth.shape != std::vector<int64_t>{z.F, z.H, z.W})
    refuse("ClipView::depth: expected f32 " + dims({z.F, z.H, z.W}) + " (the frames' F,H,W), got " + clip.depth.describe());
  if (!clip.depth.data) refuse("ClipView::depth: the view's data pointer is null (give the depth's memory)");
  if (!clip.poses.empty() && int64_t(clip.poses.size()) != z.F)
    refuse("ClipView::poses: " + std::to_string(clip.poses.size()) + " poses for " + std::to_string(z.F) +
           " frames: give one per frame, or none to use RunOptions::render.trajectory");
  return z;
}

// The run's options: the file options refused, the size and frame count the clip's.
RunOptions clip_options(const RunOptions& options, const ClipSize& z, bool poses) {
  RunOptions o = options;
  const RenderJob& j = o.render;
  auto must_be_empty = [](const std::filesystem::path& p, const char* name, const char* why) {
    if (!p.empty()) refuse(std::string("RunOptions::render.") + name + " is \"" + p.string() + "\": leave it empty (" + why + ")");
  };
  must_be_empty(j.video, "video", "the clip's frames replace the video file");
  must_be_empty(j.depth, "depth", "ClipView::depth replaces the depth file");
  must_be_empty(j.depth_model, "depth_model", "give the clip's depth in ClipView::depth, e.g. from dvs::DepthEstimator");
  must_be_empty(j.out_dir, "out_dir", "the results go into the ClipResultViews; nothing is written but the caches");
  if (j.height != z.H || j.width != z.W)
    refuse("RunOptions::render.height/width are " + std::to_string(j.height) + "x" + std::to_string(j.width) +
           " but the frames are " + std::to_string(z.H) + "x" + std::to_string(z.W) + " (HxW): set them to the frames' size");
  if (j.frames != 0 && j.frames != z.F)
    refuse("RunOptions::render.frames is " + std::to_string(j.frames) + " but the clip has " + std::to_string(z.F) +
           " frames: set it to 0 or " + std::to_string(z.F));
  o.render.frames = int(z.F);
  if (poses) o.render.trajectory = "ClipView::poses";  // what messages about the path name
  return o;
}

std::vector<glm::dmat4> pose_matrices(const std::vector<Pose>& poses) {
  std::vector<glm::dmat4> out;
  for (size_t i = 0; i < poses.size(); ++i) {
    const auto& m = poses[i].m;
    for (double v : m)
      if (!std::isfinite(v)) refuse("ClipView::poses[" + std::to_string(i) + "] holds a value that is not finite");
    if (m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1)
      refuse("ClipView::poses[" + std::to_string(i) + "]: the bottom row must be 0 0 0 1 (Pose::m is row-major: a "
             "column-major matrix must be transposed)");
    glm::dmat4 T;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) T[c][r] = m[size_t(r * 4 + c)];  // glm is column-major
    out.push_back(T);
  }
  return out;
}

void put_frames(const HostTensor& frames, const HostView& view) {
  if (!view.data) return;
  if (view.type == ElementType::f32) {
    std::memcpy(view.data, frames.data.data(), frames.bytes());
    return;
  }
  const int64_t F = frames.shape[0], plane = frames.shape[2] * frames.shape[3];
  const float* src = frames.as<float>();
  auto* dst = static_cast<uint8_t*>(view.data);
  for (int64_t f = 0; f < F; ++f)
    for (int64_t i = 0; i < plane; ++i)
      for (int64_t c = 0; c < 3; ++c) dst[(f * plane + i) * 3 + c] = unit_to_level(src[(f * 3 + c) * plane + i]);
}

// The ends of a run on a clip in memory: the clip from memory, the results into the views, nothing on disk but the
// caches.
class ClipEnds : public RunEnds {
 public:
  ClipEnds(vk::Context& ctx, ClipInput clip, std::vector<std::string> key, bool poses, const ClipResultViews& out)
      : ctx_(ctx), clip_(std::move(clip)), key_(std::move(key)), poses_(poses), out_(out) {}
  void check(const RunOptions& o) override {
    PreflightScope scope;
    scope.input_files = false;
    scope.trajectory = !poses_;
    scope.device = &ctx_.caps();
    require_preflight(o, JobKind::run, scope);
  }
  std::vector<std::string> input_key(const RunOptions&) const override { return key_; }
  RenderedInput input(vk::Context& ctx, const RunOptions& o, StageTracker& stages) override {
    return render_clip_input(ctx, o.render, clip_, stages);
  }
  void write(vk::Context& ctx, const RunResults& r, RunReport&, StageTracker& stages) override {
    stages.begin("write", "copying the results into the application's memory");
    put_frames(r.output, out_.output);
    put_frames(r.in.render, out_.render);
    if (out_.mask.data) std::memcpy(out_.mask.data, r.in.mask.data.data(), r.in.mask.bytes());
    if (out_.latent.data) {
      const HostTensor latent = r.latent.download(ctx);
      if (latent.shape != out_.latent.shape)
        throw Error("internal: the sampled latent is [" + shape_str(latent.shape) + "], the view " + out_.latent.describe());
      std::memcpy(out_.latent.data, latent.data.data(), latent.bytes());
    }
    stages.end();
  }
  void finish(const RunOptions&, const RunReport&, const RunRecordExtras&, StageTracker& stages) override {
    stages.check_cancelled();
  }

 private:
  vk::Context& ctx_;
  ClipInput clip_;
  std::vector<std::string> key_;
  bool poses_;
  ClipResultViews out_;
};

}  // namespace

RunReport run_pipeline(Context& ctx, const RunOptions& options, const ClipView& clip, const ClipResultViews& out,
                       const ProgressFn& progress, const CancelFn& cancelled) {
  const ClipSize z = check_clip(clip);
  const bool poses = !clip.poses.empty();
  const RunOptions o = clip_options(options, z, poses);
  check_result_view("ClipResultViews::output", out.output, z.F, z.H, z.W, true);
  check_result_view("ClipResultViews::render", out.render, z.F, z.H, z.W, false);
  check_f32_view("ClipResultViews::mask", out.mask, {z.F, z.H, z.W}, "the clip's F,H,W");
  if (out.latent.data) {
    if (!std::filesystem::is_directory(o.model))
      refuse("RunOptions::model " + o.model.string() + ": no such model folder (give the CogVideoX-5b-I2V folder)");
    check_f32_view("ClipResultViews::latent", out.latent, clip_latent_shape(o.model, z.F, z.H, z.W),
                   "[Fl,C,h,w] from the model's VAE config");
  }
  // The clip converted (and its depth checked as a depth file's) before any device work.
  HostTensor depth_values({z.F, z.H, z.W}, DType::f32);
  std::memcpy(depth_values.data.data(), clip.depth.data, depth_values.bytes());
  HostTensor rgb;
  if (clip.frames.type == ElementType::u8) {
    rgb = frames_from_levels(static_cast<const uint8_t*>(clip.frames.data), z.F, z.H, z.W);
  } else {
    rgb = HostTensor({z.F, 3, z.H, z.W}, DType::f32);
    std::memcpy(rgb.data.data(), clip.frames.data, rgb.bytes());
  }
  std::optional<std::vector<glm::dmat4>> matrices;
  if (poses) matrices = pose_matrices(clip.poses);
  std::vector<std::string> key = clip_input_key(clip.frames.data, size_t(clip.frames.bytes()),
                                                clip.frames.type == ElementType::u8 ? "u8" : "f32", depth_values,
                                                matrices, o.render.trajectory);
  ClipEnds ends(ctx.internal(), clip_input(o.render, std::move(rgb), depth_values, "ClipView::depth", matrices),
                std::move(key), poses, out);
  StageTracker stages(progress, cancelled);
  stages.set_memory_advice([&o](const std::string& stage) { return out_of_memory_advice(o, stage); });
  return stages.run([&] { return run_stages(o, ends, &ctx.internal(), stages); });
}

}  // namespace dvs
