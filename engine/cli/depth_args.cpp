#include "depth_args.hpp"

#include <algorithm>
#include <string>

namespace dvs::cli {

void parse_depth_source(const Args& a, RenderJob& job) {
  if (a.has("depth") && a.has("depth-model")) a.fail("give --depth FILE or --depth-model FILE.pth, not both");
  if (!a.has("depth") && !a.has("depth-model"))
    a.fail("--depth FILE (per-frame depth) or --depth-model FILE.pth (estimate it: video_depth_anything_vits.pth "
           "from the Hugging Face page depth-anything/Video-Depth-Anything-Small) is required");
  if (a.has("depth-input-size") && !a.has("depth-model")) a.fail("--depth-input-size needs --depth-model");
  if (a.has("depth-model") && a.has("metric-depth"))
    a.fail("--metric-depth is for --depth files; with --depth-model the checkpoint decides (metric_* files give depth)");
  if (a.has("depth")) {
    job.depth = a.str("depth");
    return;
  }
  job.depth_model = a.str("depth-model");
  job.depth_input_size = depth_input_size(a, "depth-input-size", job.depth_input_size);
}

int depth_input_size(const Args& a, const std::string& option, int fallback) {
  const int n = a.integer(option, fallback, 14, 4096);
  if (n % 14)
    a.fail("--" + option + " must be a multiple of 14 (the model's patch size), got " + std::to_string(n) + "; e.g. " +
           std::to_string(n / 14 * 14) + " or " + std::to_string(std::min(4088, n / 14 * 14 + 14)));
  return n;
}

}  // namespace dvs::cli
