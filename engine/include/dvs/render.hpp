// Stage 2 on its own: lift a video with its depth to point clouds, move them along a camera path and
// splat them into the new views. What `dvs render` runs.
#pragma once
#include <filesystem>
#include <functional>
#include <string>

#include "dvs/api.hpp"

namespace dvs {

struct RenderJob {
  std::filesystem::path video, depth, out_dir;
  // Video-Depth-Anything checkpoint (.pth or .safetensors): the depth is estimated from the video (and cached)
  // instead of read from `depth`, which is then set to the estimate.
  std::filesystem::path depth_model;
  int depth_input_size = 518;        // its network input's short side
  std::filesystem::path depth_cache_dir;  // dvs render only: the cache folder (dvs/cache.hpp); empty = $DVS_CACHE_DIR, else ~/.cache/dvs
  bool depth_cache = true;                // dvs render only: false = estimate again even when cached
  std::string trajectory = "loop1";  // preset name ("pan_left:30" sets a magnitude), or a .txt/.json/.gltf/.glb file
  int frames = 49;                   // first N frames (0 = all)
  int height = 480, width = 720;     // working size
  bool squash = false;               // resize by squashing (official) instead of crop
  bool metric_depth = false;         // depth file holds metric depth instead of disparity
  bool trim_depth = false;           // allow a depth file with more frames than the video uses
  std::string depth_fit = "error";   // depth of another aspect ratio than the video: error | stretch | crop
  double fx = 0, fy = 0, cx = 0, cy = 0;  // 0 = the official default (f = 500 at 1024×576), scaled
  bool hard_points = false;          // z-buffer point splatting instead of the soft bilinear splat
  bool export_glb = true;            // scene.glb: trajectory + frame-0 point cloud
  bool save_npy = false;             // also render.npy: the render before video encoding, [F,3,H,W] f32 in [−1,1]
  std::string device;
};

struct RenderSummary {
  int frames = 0, height = 0, width = 0;
  double fps = 0;
  double seconds_decode = 0, seconds_render = 0, seconds_write = 0;
  std::filesystem::path render_mp4, mask_mp4, mask_npy, poses_json, scene_glb;
  std::filesystem::path render_npy;  // empty unless RenderJob::save_npy
};

// Writes render.mp4, mask.mp4, mask.npy ([F,H,W] f32, 1 = visible), poses.json and scene.glb into
// out_dir (created), and render.npy with RenderJob::save_npy. `progress` receives short status lines. `cancelled` is polled through the depth estimate
// (--depth-model) and before the render; true stops with dvs::Cancelled.
DVS_API RenderSummary render_novel_view(const RenderJob& job, const std::function<void(const std::string&)>& progress = {},
                                        const std::function<bool()>& cancelled = {});

}  // namespace dvs
