#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <filesystem>
#include <vector>

#include "dvs/error.hpp"
#include "dvs/render.hpp"
#include "geometry/splat.hpp"
#include "geometry/splat_memory.hpp"
#include "geometry/trajectory_gltf.hpp"
#include "geometry/trajectory_json.hpp"
#include "io/depth.hpp"
#include "pipeline/depth_source.hpp"
#include "dvs/duration_text.hpp"
#include "io/library_log.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "vk/context.hpp"
#include "pipeline/render_stage.hpp"
#include "io/option_names.hpp"
#include "pipeline/output_lock.hpp"
#include "pipeline/run_outputs.hpp"

namespace dvs {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// "3, 5-8" for frames {3, 5, 6, 7, 8}.
std::string frame_list(const std::vector<int>& frames) {
  std::string out;
  for (size_t i = 0; i < frames.size();) {
    size_t j = i;
    while (j + 1 < frames.size() && frames[j + 1] == frames[j] + 1) ++j;
    if (!out.empty()) out += ", ";
    out += std::to_string(frames[i]);
    if (j > i) out += '-', out += std::to_string(frames[j]);
    i = j + 1;
  }
  return out;
}

void require_video_file(const RenderJob& job) {
  if (!std::filesystem::is_regular_file(job.video)) throw Error(job.video.string() + ": no such video file (give " + option_name("RenderJob::video") + ")");
}

}  // namespace

// The frames that show nothing of the scene: see render_stage.hpp.
void check_visibility(const HostTensor& mask, const RenderJob& job, double radius,
                      const std::function<void(const std::string&)>& say, const std::string& where_the_mask_is) {
  const int64_t F = mask.shape[0], plane = mask.shape[1] * mask.shape[2];
  std::vector<int> empty;
  double least = 1, sum = 0;
  int least_frame = 0;
  for (int64_t f = 0; f < F; ++f) {
    int64_t seen = 0;
    for (int64_t i = 0; i < plane; ++i) seen += mask.as<float>()[f * plane + i] > 0.0f;
    const double share = double(seen) / double(plane);
    sum += share;
    if (share < least) least = share, least_frame = int(f);
    if (seen == 0) empty.push_back(int(f));
  }
  char summary[96];
  std::snprintf(summary, sizeof summary, "visible pixels: %.0f%% on average, least %.0f%% (frame %d)", 100 * sum / F,
                100 * least, least_frame);
  say(summary);
  if (empty.empty()) return;
  // A clip run's poses in memory are named as such (clip_run.cpp sets that name), a path the job names by its field.
  const std::string path =
      job.trajectory == "ClipView::poses" ? job.trajectory : option_name("RenderJob::trajectory") + " " + job.trajectory;
  const std::string which = path + ": frame" + (empty.size() > 1 ? "s " : " ") +
                            frame_list(empty) + " (" + std::to_string(empty.size()) + " of " + std::to_string(F) +
                            ") show nothing of the scene (0% of the pixels visible)";
  char r[32];
  std::snprintf(r, sizeof r, "%.3g", radius);
  const int64_t after_first = int64_t(empty.size()) - (empty.front() == 0 ? 1 : 0);
  if (F > 1 && after_first == F - 1)
    throw Error(which + ": the camera leaves the scene at once. Check the move's size (pan/tilt/arc in degrees, "
                "dolly/truck in multiples of the orbit radius, " + std::string(r) + " here), a .json file's "
                "\"convention\" (world_to_camera or camera_to_world) and \"axes\" (opencv or opengl), and that the "
                "depth is what it claims (" + option_name("RenderJob::metric_depth") + " for metric depth)");
  log_warning(which + "; the model has to invent them. Look at " + where_the_mask_is + ", or use a smaller move");
}

// The default camera when none is given (Intrinsics::dvs_default: the official one under --resize squash, the
// cover-scaled one under crop), else the user's --intrinsics.
geometry::Intrinsics job_intrinsics(const RenderJob& job) {
  const int W = job.width, H = job.height;
  geometry::Intrinsics K = geometry::Intrinsics::dvs_default(W, H, job.squash);
  if (job.fx != 0 || job.fy != 0 || job.cx != 0 || job.cy != 0) {
    if (!(job.fx > 0 && job.fy > 0 && job.cx > 0 && job.cy > 0))
      throw Error(option_name("RenderJob::fx/fy/cx/cy") +
                  " needs all four of fx,fy,cx,cy (in pixels of the working size), all > 0");
    K.fx = job.fx, K.fy = job.fy, K.cx = job.cx, K.cy = job.cy, K.width = W, K.height = H;
  }
  K.validate();
  return K;
}

std::optional<std::string> render_limits_problem(const RenderJob& job, const vk::DeviceCaps& d) {
  const geometry::SplatLimits limits{d.max_storage_buffer_range, d.max_memory_allocation_size, d.max_workgroup_count[0],
                                     d.max_workgroup_count[1],
                                     "device " + d.name + (d.forced_limits.any() ? " lowered by DVS_LIMITS" : "")};
  const auto fp = geometry::splat_footprint(std::max(1, job.frames), job.height, job.width, job.hard_points, false, limits);
  if (fp.problem.empty()) return std::nullopt;
  return fp.problem;
}

void prepare_out_dir(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw Error(dir.string() + ": cannot create the output folder (" + (ec ? ec.message() : "not a folder") + ")");
  auto probe = dir / ".dvs-write-test";
  { std::ofstream(probe) << "x"; }
  if (!std::filesystem::exists(probe)) throw Error(dir.string() + ": the output folder is not writable");
  std::filesystem::remove(probe, ec);
}

RenderedInput render_stage(vk::Context& ctx, const RenderJob& job, const std::function<void(const std::string&)>& say_fn) {
  auto say = [&](const std::string& s) {
    if (say_fn) say_fn(s);
  };
  if (job.height <= 0 || job.width <= 0 || job.height % 8 || job.width % 8)
    throw Error(option_name("RenderJob::height/width") + " must be positive multiples of 8 (the VAE works on 8×8 pixel cells), got " +
                std::to_string(job.height) + "x" + std::to_string(job.width));
  if (job.frames < 0) throw Error(option_name("RenderJob::frames") + " must be ≥ 0 (0 = all frames)");
  // Check everything the user gave before any long work.
  if (!depth_source_exists(job.depth)) throw Error(job.depth.string() + ": no such depth file or folder");
  const DepthFit depth_fit = parse_depth_fit(job.depth_fit);
  require_video_file(job);
  if (auto p = render_limits_problem(job, ctx.caps())) throw Error(*p);  // before the decode and the output folder
  prepare_out_dir(job.out_dir);

  RenderedInput r;
  auto t0 = std::chrono::steady_clock::now();
  VideoReadOptions vo;
  vo.max_frames = job.frames;
  vo.height = job.height;
  vo.width = job.width;
  vo.resize = job.squash ? ResizeMode::squash : ResizeMode::crop;
  VideoInfo vi;
  r.rgb = read_video(job.video, vo, &vi);
  r.fps = vi.fps;
  const int F = int(r.rgb.shape[0]), H = job.height, W = job.width;
  say("decoded " + std::to_string(F) + " frames of " + job.video.string() + " (" + std::to_string(vi.height) + "x" +
      std::to_string(vi.width) + " at " + std::to_string(vi.fps).substr(0, 5) + " fps) -> " + std::to_string(H) +
      "x" + std::to_string(W) + " (HxW)");

  DepthOptions dopt;
  dopt.values = job.metric_depth ? DepthValues::depth : DepthValues::disparity;
  HostTensor depth = load_depth(job.depth, dopt);
  // Depth for the whole source clip (what a video depth estimator writes) follows the video's --frames cut.
  const bool whole_clip = vi.frames_in_file > 0 && depth.shape[0] == vi.frames_in_file;
  r.depth = map_depth_to_video(depth, F, {vi.height, vi.width, H, W, vo.resize}, depth_fit,
                               job.trim_depth || whole_clip, job.depth.string());
  r.seconds_decode = seconds_since(t0);

  r.K = job_intrinsics(job);
  const double radius = geometry::official_radius(centre_depth(r.depth));
  r.trajectory = geometry::load_trajectory(job.trajectory, F, radius);
  say("trajectory " + r.trajectory.description);
  for (const auto& w : r.trajectory.warnings) log_warning(w);  // a warning, not progress

  auto t1 = std::chrono::steady_clock::now();
  geometry::SplatOptions sopt;
  sopt.mode = job.hard_points ? geometry::SplatMode::hard_point : geometry::SplatMode::soft_bilinear;
  say("rendering on " + ctx.caps().name);
  geometry::RenderedClip clip = geometry::render_clip(ctx, r.rgb, r.depth, r.trajectory, r.K, sopt);
  r.render = std::move(clip.render);
  r.mask = std::move(clip.mask);
  r.seconds_render = seconds_since(t1);
  check_visibility(r.mask, job, radius, say, "mask.mp4");
  return r;
}

HostTensor mask_as_video(const HostTensor& mask) {
  HostTensor v = mask;  // {0,1} -> {−1,1}: black holes, white visible
  for (int64_t i = 0; i < v.numel(); ++i) v.as<float>()[i] = v.as<float>()[i] * 2 - 1;
  return v;
}

RenderSummary render_novel_view(const RenderJob& job_in, const std::function<void(const std::string&)>& progress,
                                const std::function<bool()>& cancelled) {
  RenderJob job = job_in;
  CreatedFolders out_folder(job.out_dir);  // removed again if the render fails before filling it
  if (!job.depth_model.empty() && job.height > 0 && job.width > 0) {  // a size that cannot render: before the estimate
    require_video_file(job);
    const std::vector<vk::DeviceCaps> devices = vk::list_devices();
    if (auto p = render_limits_problem(job, devices.at(vk::select_device(devices, job.device)))) throw Error(*p);
  }
  if (!job.depth_model.empty()) {  // estimated (or cached) first, in a context of its own
    const nlohmann::json d = resolve_depth_model(
        job, job.depth_cache_dir, !job.depth_cache,
        [&, last = std::chrono::steady_clock::time_point()](const std::string&, int step, int total,
                                                             const std::string& note) mutable {
          // Steps come many per window: a line every few seconds says where the estimate is.
          const auto now = std::chrono::steady_clock::now();
          if (!progress || (total > 0 && step < total && now - last < std::chrono::seconds(2))) return;
          last = now;
          progress(total > 0 ? "depth: step " + std::to_string(step) + "/" + std::to_string(total) + " (" + note + ")"
                             : "depth: " + note);
        },
        cancelled);
    if (progress) {
      if (d.at("from_cache").get<bool>()) {
        progress("depth from the cache: " + d.at("file").get<std::string>());
      } else {
        const double sec = d.at("seconds").get<double>();
        const int frames = d.at("estimate").at("frames").get<int>();
        char rate[96];
        std::snprintf(rate, sizeof rate, " in %s (%.3g frames/s)", duration_text(sec).c_str(), frames / std::max(sec, 1e-9));
        progress("depth estimated" + std::string(rate) + ": " + d.at("file").get<std::string>());
      }
    }
  }
  if (cancelled && cancelled()) throw Cancelled();
  const OutputLock out_lock(job.out_dir);  // before the folder is prepared: no other process writes into it
  vk::ContextOptions copt;
  copt.device = job.device;
  copt.cache_dir = job.depth_cache_dir;  // the pipeline cache in the cache folder, as DVS_CACHE_DIR puts it
  vk::Context ctx(copt);
  RenderedInput in = render_stage(ctx, job, progress);
  RenderSummary sum;
  sum.seconds_decode = in.seconds_decode;
  sum.seconds_render = in.seconds_render;
  sum.frames = int(in.rgb.shape[0]);
  sum.height = job.height;
  sum.width = job.width;
  sum.fps = in.fps;

  auto t2 = std::chrono::steady_clock::now();
  const auto& dir = job.out_dir;
  sum.render_mp4 = dir / "render.mp4";
  sum.mask_mp4 = dir / "mask.mp4";
  sum.mask_npy = dir / "mask.npy";
  sum.poses_json = dir / "poses.json";
  write_video(sum.render_mp4, in.render, in.fps);
  write_video(sum.mask_mp4, mask_as_video(in.mask), in.fps);
  write_npy(sum.mask_npy, in.mask);
  if (job.save_npy) {  // the exact values (render.mp4 is lossy), to compare with other renders
    sum.render_npy = dir / "render.npy";
    write_npy(sum.render_npy, in.render);
  }
  geometry::write_trajectory_json(sum.poses_json, in.trajectory);
  if (job.export_glb) {
    sum.scene_glb = dir / "scene.glb";
    geometry::PointCloud pc =
        geometry::point_cloud_from_rgbd(in.rgb.as<float>(), in.depth.as<float>(), job.height, job.width, in.K, 2);
    geometry::GlbExportOptions gopt;
    gopt.fps = in.fps;
    gopt.intrinsics = &in.K;
    geometry::write_trajectory_glb(sum.scene_glb, in.trajectory, &pc, gopt);
  }
  sum.seconds_write = seconds_since(t2);
  out_folder.keep();
  return sum;
}

}  // namespace dvs
