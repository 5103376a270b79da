// `dvs render`: the geometry stage alone (render + visibility mask along a camera path).
#include <iostream>

#include "args.hpp"
#include "commands.hpp"
#include "depth_args.hpp"
#include "interrupt.hpp"
#include "dvs/error.hpp"
#include "dvs/render.hpp"
#include "pipeline/duration_text.hpp"

namespace dvs::cli {

static const char* kRenderHelp =
    "usage: dvs render --video V (--depth D | --depth-model FILE.pth) --out DIR [options]\n"
    "\n"
    "Lifts every frame of V with its depth to a point cloud, moves it along the camera path and splats it into\n"
    "the new view. Writes DIR/render.mp4, mask.mp4, mask.npy ([F,H,W] f32, 1 = visible), poses.json and\n"
    "scene.glb (trajectory + frame-0 point cloud, for any glTF viewer).\n"
    "\n"
    "  --video V             input video (any size and fps)\n"
    "  --depth D             per-frame depth: .npy/.npz [N,H,W] (or [N,H,W,1]; float or 16-bit; FILE.npz:KEY\n"
    "                        picks an array, default key 'depths'), a folder of 16-bit PNG/EXR frames (natural\n"
    "                        name order: d_2 before d_10) or a grayscale video\n"
    "  --depth-model FILE    instead of --depth: estimate the depth with Video-Depth-Anything (video_depth_anything_\n"
    "                        vits.pth etc., see README); cached in $DVS_CACHE_DIR or ~/.cache/dvs (--cache-dir DIR)\n"
    "                        by the video's bytes, the model and the settings; --no-cache estimates again\n"
    "  --depth-input-size N  its network input's short side (default 518)\n"
    "  --metric-depth        D holds metric depth (default: disparity, as Video-Depth-Anything writes)\n"
    "  --trim-depth          allow D to have more frames than the video uses\n"
    "  --depth-fit error|stretch|crop  depth of another aspect ratio (or orientation) than the video: refuse\n"
    "                        (error, the default), scale each axis (stretch) or cut its centre (crop)\n"
    "  --trajectory T        loop1..loop4, wave1, oscillating_wave (official), pan_left, pan_right, tilt_up,\n"
    "                        tilt_down, dolly_in, dolly_out, truck_left, truck_right, arc_left, arc_right\n"
    "                        (NAME:MAGNITUDE sets degrees or radius fractions), or a .txt (official three-line\n"
    "                        format), .json (4x4 poses) or .gltf/.glb camera animation (default loop1)\n"
    "  --out DIR             output folder (created)\n"
    "  --frames N            first N frames (default 49; 0 = all)\n"
    "  --size HxW            working size (default 480x720; multiples of 8)\n"
    "  --resize crop|squash  keep the aspect ratio and crop the centre (default), or squash (official)\n"
    "  --intrinsics fx,fy,cx,cy  in pixels of the working size (default: f = 500 at 1024x576, scaled)\n"
    "  --points              hard z-buffer point splatting instead of the soft bilinear splat\n"
    "  --no-glb              skip scene.glb\n"
    "  --device I|NAME       Vulkan device\n";

int run_render(const std::vector<std::string>& argv) {
  Args a("render", argv,
         {"video", "depth", "depth-model", "depth-input-size", "cache-dir", "trajectory", "out", "frames", "size", "resize",
          "intrinsics", "device", "depth-fit"},
         {"metric-depth", "trim-depth", "points", "no-glb", "no-cache"});
  if (a.help()) {
    std::cout << kRenderHelp;
    return 0;
  }
  RenderJob job;
  job.video = a.required("video");
  parse_depth_source(a, job);
  job.depth_cache_dir = a.str("cache-dir");
  job.depth_cache = !a.has("no-cache");
  job.out_dir = a.required("out");
  job.trajectory = a.str("trajectory", job.trajectory);
  job.frames = a.integer("frames", job.frames, 0, 100000);
  auto [h, w] = a.size("size", {job.height, job.width});
  job.height = h;
  job.width = w;
  std::string resize = a.str("resize", "crop");
  if (resize != "crop" && resize != "squash") a.fail("--resize must be crop or squash, got '" + resize + "'");
  job.squash = resize == "squash";
  job.metric_depth = a.has("metric-depth");
  job.trim_depth = a.has("trim-depth");
  job.depth_fit = a.str("depth-fit", "error");
  if (job.depth_fit != "error" && job.depth_fit != "stretch" && job.depth_fit != "crop")
    a.fail("--depth-fit must be error, stretch or crop, got '" + job.depth_fit + "'");
  job.hard_points = a.has("points");
  job.export_glb = !a.has("no-glb");
  job.device = a.str("device");
  if (a.has("intrinsics")) {
    auto k = a.numbers("intrinsics", 4);
    job.fx = k[0], job.fy = k[1], job.cx = k[2], job.cy = k[3];
  }
  RenderSummary s = render_novel_view(job, [](const std::string& line) { std::cerr << "dvs: " << line << "\n"; }, interrupted);
  std::cout << "rendered " << s.frames << " frames at " << s.height << "x" << s.width << " (HxW)" << " (decode " << duration_text(s.seconds_decode)
            << ", render " << duration_text(s.seconds_render) << ", write " << duration_text(s.seconds_write) << ")\n"
            << "  " << s.render_mp4.string() << "\n  " << s.mask_mp4.string() << "\n  " << s.mask_npy.string() << "\n  "
            << s.poses_json.string() << "\n";
  if (!s.scene_glb.empty()) std::cout << "  " << s.scene_glb.string() << "\n";
  return 0;
}

}  // namespace dvs::cli
