#include <chrono>
#include <fstream>
#include <filesystem>

#include "dvs/error.hpp"
#include "dvs/render.hpp"
#include "geometry/splat.hpp"
#include "geometry/trajectory_gltf.hpp"
#include "geometry/trajectory_json.hpp"
#include "io/depth.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "vk/context.hpp"

namespace dvs {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
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

}  // namespace

RenderSummary render_novel_view(const RenderJob& job, const std::function<void(const std::string&)>& progress) {
  auto say = [&](const std::string& s) {
    if (progress) progress(s);
  };
  if (job.height <= 0 || job.width <= 0 || job.height % 8 || job.width % 8)
    throw Error("--size must be positive multiples of 8 (the VAE works on 8×8 pixel cells), got " +
                std::to_string(job.height) + "x" + std::to_string(job.width));
  if (job.frames < 0) throw Error("--frames must be ≥ 0 (0 = all frames)");
  // Check everything the user gave before any long work.
  if (!std::filesystem::exists(job.depth)) throw Error(job.depth.string() + ": no such depth file or folder");
  prepare_out_dir(job.out_dir);

  RenderSummary sum;
  auto t0 = std::chrono::steady_clock::now();
  VideoReadOptions vo;
  vo.max_frames = job.frames;
  vo.height = job.height;
  vo.width = job.width;
  vo.resize = job.squash ? ResizeMode::squash : ResizeMode::crop;
  VideoInfo vi;
  HostTensor rgb = read_video(job.video, vo, &vi);
  const int F = int(rgb.shape[0]), H = job.height, W = job.width;
  say("decoded " + std::to_string(F) + " frames of " + job.video.string() + " (" + std::to_string(vi.width) + "x" +
      std::to_string(vi.height) + " at " + std::to_string(vi.fps).substr(0, 5) + " fps) -> " + std::to_string(W) +
      "x" + std::to_string(H));

  DepthOptions dopt;
  dopt.values = job.metric_depth ? DepthValues::depth : DepthValues::disparity;
  HostTensor z = fit_depth_to_video(load_depth(job.depth, dopt), F, H, W, job.trim_depth, job.depth.string());
  sum.seconds_decode = seconds_since(t0);

  geometry::Intrinsics K = geometry::Intrinsics::official_default(W, H);
  if (job.fx > 0 || job.fy > 0 || job.cx > 0 || job.cy > 0) {
    if (!(job.fx > 0 && job.fy > 0 && job.cx > 0 && job.cy > 0))
      throw Error("--intrinsics needs all four of fx,fy,cx,cy (in pixels of the working size), all > 0");
    K.fx = job.fx, K.fy = job.fy, K.cx = job.cx, K.cy = job.cy, K.width = W, K.height = H;
  }
  K.validate();
  geometry::Trajectory traj = geometry::load_trajectory(job.trajectory, F, geometry::official_radius(centre_depth(z)));
  say("trajectory " + traj.description);

  auto t1 = std::chrono::steady_clock::now();
  vk::ContextOptions copt;
  copt.device = job.device;
  vk::Context ctx(copt);
  geometry::SplatOptions sopt;
  sopt.mode = job.hard_points ? geometry::SplatMode::hard_point : geometry::SplatMode::soft_bilinear;
  say("rendering on " + ctx.caps().name);
  geometry::RenderedClip clip = geometry::render_clip(ctx, rgb, z, traj, K, sopt);
  sum.seconds_render = seconds_since(t1);

  auto t2 = std::chrono::steady_clock::now();
  const auto& dir = job.out_dir;
  sum.render_mp4 = dir / "render.mp4";
  sum.mask_mp4 = dir / "mask.mp4";
  sum.mask_npy = dir / "mask.npy";
  sum.poses_json = dir / "poses.json";
  write_video(sum.render_mp4, clip.render, vi.fps);
  HostTensor mask_video = clip.mask;  // {0,1} -> {−1,1} so it shows black/white
  for (int64_t i = 0; i < mask_video.numel(); ++i) mask_video.as<float>()[i] = mask_video.as<float>()[i] * 2 - 1;
  write_video(sum.mask_mp4, mask_video, vi.fps);
  write_npy(sum.mask_npy, clip.mask);
  geometry::write_trajectory_json(sum.poses_json, traj);
  if (job.export_glb) {
    sum.scene_glb = dir / "scene.glb";
    geometry::PointCloud pc = geometry::point_cloud_from_rgbd(rgb.as<float>(), z.as<float>(), H, W, K, 2);
    geometry::GlbExportOptions gopt;
    gopt.fps = vi.fps;
    gopt.intrinsics = &K;
    geometry::write_trajectory_glb(sum.scene_glb, traj, &pc, gopt);
  }
  sum.seconds_write = seconds_since(t2);
  sum.frames = F;
  sum.height = H;
  sum.width = W;
  sum.fps = vi.fps;
  return sum;
}

}  // namespace dvs
