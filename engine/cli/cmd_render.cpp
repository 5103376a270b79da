// `dvs render`: the geometry stage alone (render + visibility mask along a camera path).
#include <iostream>
#include <tuple>

#include "args.hpp"
#include "commands.hpp"
#include "depth_args.hpp"
#include "interrupt.hpp"
#include "dvs/error.hpp"
#include "dvs/preflight.hpp"
#include "dvs/render.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "dvs/duration_text.hpp"

namespace dvs::cli {
namespace {

const CommandHelp kRenderHelp{
    "dvs render --video V (--depth D | --depth-model FILE.pth) --out DIR [options]",
    "Lifts every frame of V with its depth to a point cloud, moves it along the camera path and splats it into\n"
    "the new view. Writes DIR/render.mp4, mask.mp4, mask.npy ([F,H,W] f32, 1 = visible), poses.json and\n"
    "scene.glb (trajectory + frame-0 point cloud, for any glTF viewer).\n",
    ""};

const OptionGroup kRenderOnly{"render",
                               {{"no-glb", "", "skip scene.glb"},
                                {"save-npy", "", "also write render.npy: the render as [F,3,H,W] f32 in [-1,1], exactly "
                                                 "as rendered (render.mp4 is lossy)"}}};

}  // namespace

int run_render(const std::vector<std::string>& argv) {
  Args a("render", kRenderHelp,
         {kClipInputs, kDepthSource, kOutFolder, kRenderOnly, kDepthCache, kDevice, kProgressOutput, kCheckOnly});
  a.parse(argv);
  if (a.help()) return 0;
  RenderJob job;
  job.video = a.required("video");
  parse_depth_source(a, job);
  job.depth_cache_dir = a.str("cache-dir");
  job.depth_cache = !a.has("no-cache");
  job.out_dir = a.required("out");
  job.trajectory = a.str("trajectory", job.trajectory);
  job.frames = a.integer("frames", job.frames, 0, 100000);
  std::tie(job.height, job.width) = a.working_size({job.height, job.width});
  const std::string resize = a.str("resize", "crop");
  if (resize != "crop" && resize != "squash") a.fail("--resize must be crop or squash, got '" + resize + "'");
  job.squash = resize == "squash";
  job.metric_depth = a.has("metric-depth");
  job.trim_depth = a.has("trim-depth");
  job.depth_fit = a.str("depth-fit", "error");
  if (job.depth_fit != "error" && job.depth_fit != "stretch" && job.depth_fit != "crop")
    a.fail("--depth-fit must be error, stretch or crop, got '" + job.depth_fit + "'");
  job.hard_points = a.has("points");
  job.export_glb = !a.has("no-glb");
  job.save_npy = a.has("save-npy");
  job.device = a.str("device");
  if (a.has("intrinsics")) {
    auto k = a.numbers("intrinsics", 4);
    job.fx = k[0], job.fy = k[1], job.cx = k[2], job.cy = k[3];
  }
  const ProgressMode mode = progress_mode(a);
  if (a.has("check")) {
    const PreflightReport r = preflight_render(job);
    if (!r.ok()) throw Error(r.message());
    for (const auto& n : r.notes)  // warnings whatever --progress says
      if (mode != ProgressMode::quiet || n.rfind("warning: ", 0) == 0) std::cerr << "  " << n << "\n";
    // stdout stays JSON Lines under --progress json: the verdict goes to stderr there.
    (mode == ProgressMode::json ? std::cerr : std::cout) << "preflight: no problem found; dvs render with these options would start\n";
    return 0;
  }
  Progress progress(mode);
  const RenderSummary s = render_novel_view(
      job,
      [&](const std::string& line) {
        if (mode == ProgressMode::bar) std::cerr << "dvs: " << line << "\n";
        else progress("render", 0, 0, line);  // json: one event per line; quiet: nothing
      },
      interrupted);
  progress.finish();
  std::cout << "rendered " << s.frames << " frames at " << s.height << "x" << s.width << " (HxW)" << " (decode " << duration_text(s.seconds_decode)
            << ", render " << duration_text(s.seconds_render) << ", write " << duration_text(s.seconds_write) << ")\n"
            << "  " << s.render_mp4.string() << "\n  " << s.mask_mp4.string() << "\n  " << s.mask_npy.string() << "\n  "
            << s.poses_json.string() << "\n";
  if (!s.scene_glb.empty()) std::cout << "  " << s.scene_glb.string() << "\n";
  if (!s.render_npy.empty()) std::cout << "  " << s.render_npy.string() << "\n";
  return 0;
}

}  // namespace dvs::cli
