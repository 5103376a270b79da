#include "preview_options.hpp"

#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

namespace preview {

const char* const kPreviewUsage =
    "usage: dvs-preview (--video VIDEO | --frame-npy FRAME.npy) (--depth DEPTH.npz|.npy | --depth-model CKPT) [options]\n"
    "\n"
    "Shows the point cloud of one video frame from a camera you fly, beside the input frame and the mask of what\n"
    "is visible. Place key poses, scrub and play the path, export it as a trajectory JSON + .glb that\n"
    "`dvs run/render --trajectory` take.\n"
    "\n"
    "inputs:\n"
    "  --video FILE         the video (.mp4, ...: dvs's video component), brought to --size as dvs render does\n"
    "  --frame-npy FILE     or the frame: u8 [H,W,3] or f32 [3,H,W] in [-1,1] (or [F,...]: see --frame-index)\n"
    "  --depth FILE         the clip's depth as `dvs depth` writes it: .npz (key depths, or FILE.npz:KEY) or .npy\n"
    "                       [F,H,W], disparity converted over the whole clip and mapped to --size as dvs render\n"
    "                       does; or one frame f32 [H,W] .npy at --size\n"
    "  --depth-model CKPT   or estimate it here (with --video): Video-Depth-Anything on the first --frames frames,\n"
    "                       as `dvs render --depth-model CKPT --frames N` does\n"
    "  --depth-input-size N its network input's short side (default 518)\n"
    "  --metric-depth       the depth holds metric depth instead of disparity\n"
    "  --frame-index N      frame N of the video / frame array and of the depth (default 0)\n"
    "  --size HxW           the working size (default 480x720)\n"
    "  --squash             squash the video to --size instead of cropping its centre (dvs render --resize squash)\n"
    "  --depth-fit MODE     depth of another aspect than the video: error (default), stretch, crop\n"
    "  --intrinsics fx,fy,cx,cy  pixels (default: dvs render's, f = 500 at 1024x576 scaled)\n"
    "  --hard-points        z-buffer point splat instead of the soft splat (dvs render --points)\n"
    "path:\n"
    "  --frames N           frames of the exported path (default 49)\n"
    "  --export FILE.json   where X writes the path (and FILE.glb beside it; default preview_path.json)\n"
    "scripted runs and timing:\n"
    "  --script FILE        input events from FILE, one a frame (see the README)\n"
    "  --screenshot-panel   a .png screenshot holds only the render panel (an .npy always does)\n"
    "  --frames-to-run N    stop after N frames and print the frame times\n"
    "device:\n"
    "  --gpu NAME           the GPU whose name contains NAME\n"
    "  --dvs-own-device     dvs on a device of its own (comparison only; default: the window's device)\n"
    "  --host-round-trip    the render and mask through host memory (comparison only; default: dvs renders into\n"
    "                       device images of the window's, drawn without a host wait)\n"
    "  --validation         the Khronos validation layer\n"
    "frame rate (motion is per second, whatever the rate):\n"
    "  --max-fps N          at most N frames a second (default 60; 0: as fast as it renders, for timing)\n"
    "  --no-vsync           IMMEDIATE or MAILBOX present where offered (default: FIFO, the display's rate)\n"
    "\n"
    "keys: W/S forward/back, A/D left/right, Q/E up/down, left-drag look, scroll speed, K key pose,\n"
    "      [ and ] scrub, P play, X export (E moves down), F12 screenshot, R back to the input view, Esc quit\n";

namespace {

int to_int(const std::string& option, const std::string& v, int lo) {
  char* end = nullptr;
  const long n = std::strtol(v.c_str(), &end, 10);
  if (end == v.c_str() || *end || n < lo || n > 1000000)
    throw std::runtime_error(option + " takes a whole number ≥ " + std::to_string(lo) + ", got '" + v + "'");
  return int(n);
}

}  // namespace

PreviewOptions parse_options(int argc, char** argv) {
  PreviewOptions o;
  std::vector<std::string> args(argv + 1, argv + argc);
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= args.size()) throw std::runtime_error(a + " needs a value (dvs-preview --help)");
      return args[++i];
    };
    if (a == "-h" || a == "--help") o.help = true;
    else if (a == "--frame-npy") o.frame_npy = value();
    else if (a == "--video") o.video = value();
    else if (a == "--squash") o.squash = true;
    else if (a == "--depth-fit") o.depth_fit = value();
    else if (a == "--depth") o.depth = value();
    else if (a == "--depth-model") o.depth_model = value();
    else if (a == "--depth-input-size") o.depth_input_size = to_int(a, value(), 14);
    else if (a == "--metric-depth") o.metric_depth = true;
    else if (a == "--hard-points") o.hard_points = true;
    else if (a == "--frame-index") o.frame_index = to_int(a, value(), 0);
    else if (a == "--frames") o.frames = to_int(a, value(), 1), o.frames_given = true;
    else if (a == "--size") {
      const std::string v = value();
      const size_t x = v.find('x');
      if (x == std::string::npos) throw std::runtime_error("--size takes HxW, e.g. 480x720, got '" + v + "'");
      o.height = to_int(a, v.substr(0, x), 8);
      o.width = to_int(a, v.substr(x + 1), 8);
    } else if (a == "--intrinsics") {
      const std::string v = value();
      std::array<double, 4> k{};
      size_t p = 0;
      for (int j = 0; j < 4; ++j) {
        char* end = nullptr;
        k[size_t(j)] = std::strtod(v.c_str() + p, &end);
        const size_t used = size_t(end - (v.c_str() + p));
        if (!used || !(k[size_t(j)] > -1e9)) throw std::runtime_error("--intrinsics takes fx,fy,cx,cy, got '" + v + "'");
        p += used;
        if (j < 3 && (p >= v.size() || v[p++] != ','))
          throw std::runtime_error("--intrinsics takes four numbers fx,fy,cx,cy separated by commas, got '" + v + "'");
      }
      if (p != v.size() || !(k[0] > 0) || !(k[1] > 0))
        throw std::runtime_error("--intrinsics takes fx,fy,cx,cy with fx, fy > 0, got '" + v + "'");
      o.intrinsics = k;
    } else if (a == "--script") o.script = value();
    else if (a == "--screenshot-panel") o.screenshot_panel = true;
    else if (a == "--frames-to-run") o.frames_to_run = to_int(a, value(), 1);
    else if (a == "--export") o.export_name = value();
    else if (a == "--gpu") o.gpu = value();
    else if (a == "--dvs-own-device") o.own_device = true;
    else if (a == "--host-round-trip") o.host_round_trip = true;
    else if (a == "--validation") o.validation = true;
    else if (a == "--no-vsync") o.vsync = false;
    else if (a == "--max-fps") o.max_fps = to_int(a, value(), 0);
    else throw std::runtime_error("unknown option '" + a + "' (dvs-preview --help lists them)");
  }
  if (o.help) return o;
  if (o.frame_npy.empty() == o.video.empty())
    throw std::runtime_error("give the frame: --video VIDEO or --frame-npy FRAME.npy, one of them (dvs-preview --help)");
  if (o.depth.empty() == o.depth_model.empty())
    throw std::runtime_error("give its depth: --depth DEPTH.npz|.npy or --depth-model CKPT, one of them (dvs-preview --help)");
  if (!o.depth_model.empty() && o.video.empty())
    throw std::runtime_error("--depth-model estimates the depth of a video: give --video VIDEO (or --depth with --frame-npy)");
  if (!o.depth_model.empty() && o.frame_index >= o.frames)  // messages name only the options given
    throw std::runtime_error("--frame-index " + std::to_string(o.frame_index) + " is past the " +
                             std::to_string(o.frames) + " frames --depth-model estimates" +
                             (o.frames_given ? " (--frames " + std::to_string(o.frames) + ")" : " by default") +
                             ": estimate at least " + std::to_string(o.frame_index + 1) +
                             " frames (--frames N) or give a frame among them");
  if (o.squash && o.video.empty()) throw std::runtime_error("--squash applies to --video only (a frame array is at --size)");
  return o;
}

}  // namespace preview
