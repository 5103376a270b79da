// `dvs depth`: per-frame disparity of a video with Video-Depth-Anything, as its run.py --save_npz writes it.
#include <cstdlib>
#include <iostream>

#include "args.hpp"
#include "depth_args.hpp"
#include "commands.hpp"
#include "dvs/depth_estimate.hpp"
#include "dvs/error.hpp"
#include "interrupt.hpp"
#include "options.hpp"
#include "progress.hpp"

namespace dvs::cli {

namespace {

const CommandHelp kDepthHelp{
    "dvs depth --video V --out FILE.npz [--depth-model FILE.pth] [options]",
    "Estimates the disparity of every frame of V with Video-Depth-Anything (windows of 32 frames aligned to each\n"
    "other, as the authors' infer_video_depth) and writes it as their run.py --save_npz does: FILE.npz holding\n"
    "'depths', f32 [N,H,W] at the frames' size (FILE.npy: the array alone). Give it to dvs run/render --depth, or\n"
    "let them estimate it themselves with --depth-model.\n",
    ""};

// dvs depth's own options: its --out is a file, its --frames defaults to all of them.
const OptionGroup kDepthEstimate{
    "depth estimate",
    {{"video", "V", "input video"},
     {"out", "FILE", ".npz (key 'depths') or .npy; written atomically"},
     {"depth-model", "FILE",
      "video_depth_anything_vits.pth (Small, Apache-2.0), _vitb / _vitl (CC-BY-NC-4.0),\n"
      "a metric_video_depth_anything_*.pth, or a .safetensors of one (default:\n"
      "$DVS_DEPTH_MODEL)"},
     {"input-size", "N", "network input's short side, a multiple of 14 (default 518, the model's)"},
     {"frames", "N", "first N frames (default 0 = all)"},
     {"max-res", "N", "scale frames whose long side exceeds N down first (default 1280; 0 = never)"}}};

// The depth cache, shared with run/render --depth-model: the same estimate is never made twice.
const OptionGroup kDepthEstimateCache{
    "cache",
    {{"cache-dir", "DIR", "the cache folder, as DVS_CACHE_DIR=DIR, shared with run/render --depth-model: the\n"
                          "estimates in DIR/inversions (default $DVS_CACHE_DIR, else ~/.cache/dvs)"},
     {"no-cache", "", "estimate again even when the cache holds this estimate"}}};

}  // namespace

std::filesystem::path depth_model_argument(const Args& a) {
  if (a.has("depth-model")) return a.str("depth-model");
  if (const char* e = std::getenv("DVS_DEPTH_MODEL"); e && *e) return e;
  a.fail("--depth-model FILE.pth is required (or set DVS_DEPTH_MODEL): download video_depth_anything_vits.pth "
         "from the Hugging Face model page depth-anything/Video-Depth-Anything-Small");
}

int run_depth(const std::vector<std::string>& argv) {
  Args a("depth", kDepthHelp, {kDepthEstimate, kDepthEstimateCache, kDevice, kProgressOutput});
  a.parse(argv);
  if (a.help()) return 0;
  const ProgressMode mode = progress_mode(a);
  DepthJob job;
  job.video = a.required("video");
  const std::filesystem::path out = a.required("out");
  if (out.extension() != ".npz" && out.extension() != ".npy") a.fail("--out must end in .npz or .npy, got " + out.string());
  job.model = depth_model_argument(a);
  job.input_size = depth_input_size(a, "input-size", job.input_size);
  job.frames = a.integer("frames", 0, 0, 1000000);
  job.max_res = a.integer("max-res", job.max_res, 0, 100000);
  job.device = a.str("device");
  job.cache_dir = a.str("cache-dir");
  job.refresh_cache = a.has("no-cache");
  Progress progress(mode);
  job.notice = [&](const std::string& line) {  // kept on screen whatever the progress mode
    progress.finish();
    std::cerr << "dvs depth: " << line << "\n";
  };
  const DepthSummary s = estimate_depth(job, out, std::ref(progress), interrupted);
  progress.finish();
  if (mode != ProgressMode::quiet) std::cerr << describe(s) << "\n";
  std::cout << out.string() << "\n";
  return 0;
}

}  // namespace dvs::cli
