// dvs/clip_run.hpp: a whole run on a clip in memory, on the application's context. The views and options are checked
// here, before any work (each error names the view or option and what to do); the stages are run_pipeline's own
// (pipeline/run_stages.hpp) with ends that take the clip from memory (pipeline/clip_input.hpp) and put the results
// into the application's views. The public calls take the context's turn at its gate (embed/context_gate.hpp); a job
// runs embed::run_clip on its own thread while it holds the context.
#include "dvs/clip_run.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <optional>

#include "dvs/error.hpp"
#include "embed/clip_run_on_device.hpp"
#include "embed/context_core.hpp"
#include "embed/device_copy.hpp"
#include "embed/public_call.hpp"
#include "embed/view_facts.hpp"
#include "io/pixel_levels.hpp"
#include "pipeline/clip_input.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/preflight.hpp"
#include "pipeline/run_stages.hpp"
#include "pipeline/settings.hpp"

namespace dvs {
namespace {

constexpr const char* kCall = "dvs::run_pipeline on a clip";

[[noreturn]] void refuse(const std::string& what) {
  throw Error(std::string(kCall) + ": " + what, ErrorKind::invalid_argument);
}

std::string dims(const std::vector<int64_t>& s) {
  std::string t;
  for (size_t i = 0; i < s.size(); ++i) t += (i ? "," : "") + std::to_string(s[i]);
  return "[" + t + "]";
}

using embed::facts;
using embed::ViewFacts;

// Where a frames-like view's pixels are: u8 [F,H,W,3] or f32 [F,3,H,W].
bool rgb8(const ViewFacts& v, int64_t F, int64_t H, int64_t W) {
  return v.type == ElementType::u8 && v.shape == std::vector<int64_t>{F, H, W, 3};
}
bool planar(const ViewFacts& v, int64_t F, int64_t H, int64_t W) {
  return v.type == ElementType::f32 && v.shape == std::vector<int64_t>{F, 3, H, W};
}

void check_result_view(const ViewFacts& v, int64_t F, int64_t H, int64_t W, bool required) {
  if (!v.given) {
    if (required) refuse(v.name + ": " + v.missing + " (give memory for the new view)");
    return;
  }
  if (!rgb8(v, F, H, W) && !planar(v, F, H, W))
    refuse(v.name + ": expected u8 " + dims({F, H, W, 3}) + " or f32 " + dims({F, 3, H, W}) +
           " (the clip's F,H,W), got " + v.text);
}

void check_f32_view(const ViewFacts& v, const std::vector<int64_t>& shape, const std::string& why) {
  if (v.given && (v.type != ElementType::f32 || v.shape != shape))
    refuse(v.name + ": expected f32 " + dims(shape) + " (" + why + "), got " + v.text);
}

// The frames' F, H, W; the frames and depth views checked.
struct ClipSize {
  int64_t F = 0, H = 0, W = 0;
};

ClipSize check_clip(const ViewFacts& frames, const ViewFacts& depth, size_t poses, const std::string& poses_name) {
  const auto& s = frames.shape;
  ClipSize z;
  if (frames.type == ElementType::u8 && s.size() == 4 && s[3] == 3) z = {s[0], s[1], s[2]};
  else if (frames.type == ElementType::f32 && s.size() == 4 && s[1] == 3) z = {s[0], s[2], s[3]};
  else refuse(frames.name + ": expected u8 [F,H,W,3] RGB or f32 [F,3,H,W] in [-1,1], got " + frames.text);
  if (!frames.given) refuse(frames.name + ": " + frames.missing + " (give the frames' memory)");
  check_clip_size(z.F, z.H, z.W, std::string(kCall) + ": " + frames.name, std::string(kCall) + ": " + frames.name);
  if (depth.type != ElementType::f32 || depth.shape != std::vector<int64_t>{z.F, z.H, z.W})
    refuse(depth.name + ": expected f32 " + dims({z.F, z.H, z.W}) + " (the frames' F,H,W), got " + depth.text);
  if (!depth.given) refuse(depth.name + ": " + depth.missing + " (give the depth's memory)");
  if (poses != 0 && int64_t(poses) != z.F)
    refuse(poses_name + ": " + std::to_string(poses) + " poses for " + std::to_string(z.F) +
           " frames: give one per frame, or none to use RunOptions::render.trajectory");
  return z;
}

// The result views checked against the clip's size (and the latent against the model's VAE config).
void check_results(const RunOptions& o, const ClipSize& z, const ViewFacts& output, const ViewFacts& render,
                   const ViewFacts& mask, const ViewFacts& latent) {
  check_result_view(output, z.F, z.H, z.W, true);
  check_result_view(render, z.F, z.H, z.W, false);
  check_f32_view(mask, {z.F, z.H, z.W}, "the clip's F,H,W");
  if (latent.given) {
    if (!std::filesystem::is_directory(o.model))
      throw Error(std::string(kCall) + ": RunOptions::model " + o.model.string() +
                  ": no such model folder (give the CogVideoX-5b-I2V folder)");
    check_f32_view(latent, clip_latent_shape(o.model, z.F, z.H, z.W), "[Fl,C,h,w] from the model's VAE config");
  }
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
  try {
    resolve(o);  // the settings (preset, steps, strength, ...) are the caller's to fix, refused before any work
  } catch (const Error& e) {
    refuse(e.what());
  }
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

// Frames [F,3,H,W] in [−1,1] in the view's form: the same f32 values, or u8 [F,H,W,3] levels rounded as the video
// writer rounds them.
HostTensor frames_as(const HostTensor& frames, ElementType type) {
  if (type == ElementType::f32) return frames;
  const int64_t F = frames.shape[0], H = frames.shape[2], W = frames.shape[3], plane = H * W;
  HostTensor levels({F, H, W, 3}, DType::u8);
  const float* src = frames.as<float>();
  auto* dst = levels.as<uint8_t>();
  for (int64_t f = 0; f < F; ++f)
    for (int64_t i = 0; i < plane; ++i)
      for (int64_t c = 0; c < 3; ++c) dst[(f * plane + i) * 3 + c] = unit_to_level(src[(f * 3 + c) * plane + i]);
  return levels;
}

// Where a run's results go: the application's host views or device buffers.
using PutResults = std::function<void(vk::Context&, const RunResults&)>;

PutResults into_host(const ClipResultViews& out) {
  return [out](vk::Context& ctx, const RunResults& r) {
    auto put = [](const HostTensor& t, const HostView& view) {
      if (!view.data) return;
      if (t.bytes() != view.bytes())  // the views were checked against the clip; never write past the application's
        throw Error("internal: " + std::to_string(t.bytes()) + " bytes of results for the view " + view.describe());
      std::memcpy(view.data, t.data.data(), t.bytes());
    };
    put(frames_as(r.output, out.output.type), out.output);
    if (out.render.data) put(frames_as(r.in.render, out.render.type), out.render);
    put(r.in.mask, out.mask);
    if (out.latent.data) put(r.latent.download(ctx), out.latent);
  };
}

// The host results uploaded and copied into the buffers, the latent copied device to device; the last copy waited for.
PutResults into_device(const ClipResultDeviceViews& out) {
  return [out](vk::Context& ctx, const RunResults& r) {
    uint64_t last = 0;
    auto put = [&](const HostTensor& t, const DeviceBufferView& view, const char* name) {
      if (view.buffer) last = embed::copy_from_tensor(ctx, Tensor::upload(ctx, t, name), view, name);
    };
    put(frames_as(r.output, out.output.type), out.output, "ClipResultDeviceViews::output");
    if (out.render.buffer) put(frames_as(r.in.render, out.render.type), out.render, "ClipResultDeviceViews::render");
    put(r.in.mask, out.mask, "ClipResultDeviceViews::mask");
    if (out.latent.buffer) last = embed::copy_from_tensor(ctx, r.latent, out.latent, "ClipResultDeviceViews::latent");
    if (last) ctx.wait(last);
  };
}

// The ends of a run on a clip in memory: the clip from memory, the results into the application's memory, nothing on
// disk but the caches.
class ClipEnds : public RunEnds {
 public:
  ClipEnds(vk::Context& ctx, ClipInput clip, std::vector<std::string> key, bool poses, PutResults put)
      : ctx_(ctx), clip_(std::move(clip)), key_(std::move(key)), poses_(poses), put_(std::move(put)) {}
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
    put_(ctx, r);
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
  PutResults put_;
};

// The run on a checked clip whose frames and depth are in host memory (the application's, or fetched from its
// buffers).
RunReport run_checked_clip(vk::Context& device, const RunOptions& o, const ClipSize& z, const ConstHostView& frames,
                           const ConstHostView& depth, const std::string& depth_name, const std::vector<Pose>& poses,
                           PutResults put, const ProgressFn& progress, const CancelFn& cancelled) {
  // The clip converted (and its depth checked as a depth file's) before any device work.
  HostTensor depth_values({z.F, z.H, z.W}, DType::f32);
  std::memcpy(depth_values.data.data(), depth.data, depth_values.bytes());
  HostTensor rgb;
  if (frames.type == ElementType::u8) {
    rgb = frames_from_levels(static_cast<const uint8_t*>(frames.data), z.F, z.H, z.W);
  } else {
    rgb = HostTensor({z.F, 3, z.H, z.W}, DType::f32);
    std::memcpy(rgb.data.data(), frames.data, rgb.bytes());
  }
  std::optional<std::vector<glm::dmat4>> matrices;
  if (!poses.empty()) matrices = pose_matrices(poses);
  std::vector<std::string> key = clip_input_key(frames.data, size_t(frames.bytes()),
                                                frames.type == ElementType::u8 ? "u8" : "f32", depth_values, matrices,
                                                o.render.trajectory);
  ClipEnds ends(device, clip_input(o.render, std::move(rgb), depth_values, depth_name, matrices), std::move(key),
                !poses.empty(), std::move(put));
  StageTracker stages(progress, cancelled);
  stages.set_memory_advice([&o](const std::string& stage) { return out_of_memory_advice(o, stage); });
  return stages.run([&] { return run_stages(o, ends, &device, stages); });
}

}  // namespace

namespace embed {

RunReport run_clip(vk::Context& device, const RunOptions& options, const ClipView& clip, const ClipResultViews& out,
                   const ProgressFn& progress, const CancelFn& cancelled) {
  const ClipSize z =
      check_clip(facts("ClipView::frames", clip.frames), facts("ClipView::depth", clip.depth), clip.poses.size(),
                 "ClipView::poses");
  const RunOptions o = clip_options(options, z, !clip.poses.empty());
  check_results(o, z, facts("ClipResultViews::output", out.output), facts("ClipResultViews::render", out.render),
                facts("ClipResultViews::mask", out.mask), facts("ClipResultViews::latent", out.latent));
  return run_checked_clip(device, o, z, clip.frames, clip.depth, "ClipView::depth", clip.poses, into_host(out),
                          progress, cancelled);
}

RunReport run_clip(vk::Context& device, const RunOptions& options, const ClipDeviceView& clip,
                   const ClipResultDeviceViews& out, const ProgressFn& progress, const CancelFn& cancelled) {
  const ViewFacts frames = facts("ClipDeviceView::frames", clip.frames), depth = facts("ClipDeviceView::depth", clip.depth);
  const ClipSize z = check_clip(frames, depth, clip.poses.size(), "ClipDeviceView::poses");
  const RunOptions o = clip_options(options, z, !clip.poses.empty());
  const ViewFacts results[4] = {facts("ClipResultDeviceViews::output", out.output),
                                facts("ClipResultDeviceViews::render", out.render),
                                facts("ClipResultDeviceViews::mask", out.mask),
                                facts("ClipResultDeviceViews::latent", out.latent)};
  check_results(o, z, results[0], results[1], results[2], results[3]);
  // Every buffer's range (and offset) before any work.
  for (const auto& [view, a] : {std::pair{&clip.frames, &frames}, {&clip.depth, &depth}, {&out.output, &results[0]},
                                {&out.render, &results[1]}, {&out.mask, &results[2]}, {&out.latent, &results[3]}})
    if (a->given) embed::check_view_fits(device, *view, view->type, view->shape, a->name);
  HostTensor frames_host = embed::fetch_view(device, clip.frames, frames.name);
  HostTensor depth_host = embed::fetch_view(device, clip.depth, depth.name);
  return run_checked_clip(device, o, z, ConstHostView{frames_host.data.data(), clip.frames.type, clip.frames.shape},
                          ConstHostView{depth_host.data.data(), ElementType::f32, clip.depth.shape}, depth.name,
                          clip.poses, into_device(out), progress, cancelled);
}

}  // namespace embed

namespace {

// The public calls: at the context's turn (they wait for another thread's call, and are refused under a job).
template <class Clip, class Results>
RunReport run_at_turn(Context& ctx, const RunOptions& options, const Clip& clip, const Results& out,
                      const ProgressFn& progress, const CancelFn& cancelled) {
  const std::shared_ptr<embed::ContextCore> core = ctx.core();
  return embed::public_call("dvs::run_pipeline", [&] {
    embed::GateUse use(core->gate, "dvs::run_pipeline");
    return embed::run_clip(*core->device, options, clip, out, progress, cancelled);
  });
}

}  // namespace

RunReport run_pipeline(Context& ctx, const RunOptions& options, const ClipView& clip, const ClipResultViews& out,
                       const ProgressFn& progress, const CancelFn& cancelled) {
  return run_at_turn(ctx, options, clip, out, progress, cancelled);
}

RunReport run_pipeline(Context& ctx, const RunOptions& options, const ClipDeviceView& clip,
                       const ClipResultDeviceViews& out, const ProgressFn& progress, const CancelFn& cancelled) {
  return run_at_turn(ctx, options, clip, out, progress, cancelled);
}

}  // namespace dvs
