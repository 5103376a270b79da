// `dvs depth`: per-frame disparity of a video with Video-Depth-Anything, as its run.py --save_npz writes it.
#include <cstdlib>
#include <iostream>

#include "args.hpp"
#include "depth_args.hpp"
#include "commands.hpp"
#include "dvs/depth_estimate.hpp"
#include "dvs/error.hpp"
#include "interrupt.hpp"
#include "progress.hpp"

namespace dvs::cli {

static const char* kDepthHelp =
    "usage: dvs depth --video V --out FILE.npz [--depth-model FILE.pth] [options]\n"
    "\n"
    "Estimates the disparity of every frame of V with Video-Depth-Anything (windows of 32 frames aligned to each\n"
    "other, as the authors' infer_video_depth) and writes it as their run.py --save_npz does: FILE.npz holding\n"
    "'depths', f32 [N,H,W] at the frames' size (FILE.npy: the array alone). Give it to dvs run/render --depth, or\n"
    "let them estimate it themselves with --depth-model.\n"
    "\n"
    "  --video V             input video\n"
    "  --out FILE            .npz (key 'depths') or .npy; written atomically\n"
    "  --depth-model FILE    video_depth_anything_vits.pth (Small, Apache-2.0), _vitb / _vitl (CC-BY-NC-4.0), a\n"
    "                        metric_video_depth_anything_*.pth, or a .safetensors of one (default: $DVS_DEPTH_MODEL)\n"
    "  --input-size N        network input's short side, a multiple of 14 (default 518, the model's)\n"
    "  --frames N            first N frames (default 0 = all)\n"
    "  --max-res N           scale frames whose long side exceeds N down first (default 1280; 0 = never)\n"
    "  --progress bar|json|none   progress output (default bar; one step per window); --quiet = none\n"
    "  --device I|NAME       Vulkan device\n";

std::filesystem::path depth_model_argument(const Args& a) {
  if (a.has("depth-model")) return a.str("depth-model");
  if (const char* e = std::getenv("DVS_DEPTH_MODEL"); e && *e) return e;
  a.fail("--depth-model FILE.pth is required (or set DVS_DEPTH_MODEL): download video_depth_anything_vits.pth "
         "from the Hugging Face model page depth-anything/Video-Depth-Anything-Small");
}

int run_depth(const std::vector<std::string>& argv) {
  Args a("depth", argv, {"video", "out", "depth-model", "input-size", "frames", "max-res", "progress", "device"}, {"quiet"});
  if (a.help()) {
    std::cout << kDepthHelp;
    return 0;
  }
  DepthJob job;
  job.video = a.required("video");
  const std::filesystem::path out = a.required("out");
  if (out.extension() != ".npz" && out.extension() != ".npy") a.fail("--out must end in .npz or .npy, got " + out.string());
  job.model = depth_model_argument(a);
  job.input_size = depth_input_size(a, "input-size", job.input_size);
  job.frames = a.integer("frames", 0, 0, 1000000);
  job.max_res = a.integer("max-res", job.max_res, 0, 100000);
  job.device = a.str("device");
  const ProgressMode mode = parse_progress_mode(a.str("progress"), a.has("quiet"));
  Progress progress(mode);
  const DepthSummary s = estimate_depth(job, out, std::ref(progress), interrupted);
  progress.finish();
  if (mode != ProgressMode::quiet)
    std::cerr << "depth of " << s.frames << " frames at " << s.height << "x" << s.width << " (HxW) with "
              << s.model_size << (s.metric ? " (metric)" : "") << ", network input " << s.input_height << "x"
              << s.input_width << ", " << s.windows << " windows: decode " << s.seconds_decode << " s, load "
              << s.seconds_load << " s, depth " << s.seconds_depth << " s (" << (s.frames / std::max(1e-9, s.seconds_depth))
              << " frames/s)\n";
  std::cout << out.string() << "\n";
  return 0;
}

}  // namespace dvs::cli
