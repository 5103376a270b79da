// dvs-preview's command line. Errors are std::runtime_error naming the option and what it takes.
#pragma once
#include <array>
#include <optional>
#include <string>

namespace preview {

struct PreviewOptions {
  std::string frame_npy;       // u8 [H,W,3] / [F,H,W,3] or f32 [3,H,W] / [F,3,H,W] in [−1,1]
  std::string video;           // or a video file (dvs's video component), brought to --size as dvs render does
  bool squash = false;         // the video is squashed to --size instead of centre-cropped (dvs render --resize squash)
  std::string depth;           // .npz / .npy [F,H,W] (or one frame [H,W]): disparity (as dvs depth writes it) unless metric_depth
  std::string depth_model;     // or a Video-Depth-Anything checkpoint: the clip's depth estimated here (--video only)
  int depth_input_size = 518;  // its network input's short side (dvs render --depth-input-size)
  std::string depth_fit = "error";  // depth of another aspect than the video (dvs render --depth-fit)
  int frame_index = 0;         // which frame of the video, frame array and depth
  int frames = 49;             // frames of the exported path
  bool frames_given = false;   // --frames was given (messages name only the options given)
  int height = 480, width = 720;
  std::optional<std::array<double, 4>> intrinsics;  // fx fy cx cy; default: dvs render's (CameraIntrinsics::dvs_default)
  bool metric_depth = false, hard_points = false;
  std::string script;          // scripted input (input_script.hpp)
  bool screenshot_panel = false;  // a .png screenshot holds only the render panel
  int frames_to_run = 0;       // stop after this many frames (0: until closed or the script quits)
  std::string export_name = "preview_path.json";  // X: this and its .glb sibling
  std::string gpu;             // substring of the GPU's name
  bool own_device = false;     // dvs on a device of its own instead of the window's (for comparison only)
  bool host_round_trip = false;  // the render through host memory instead of into the window's device images
  bool validation = false;
  bool vsync = true;           // FIFO present (--no-vsync: IMMEDIATE or MAILBOX where offered)
  int max_fps = 60;            // frames a second at most (0: no cap; frame_pacing.hpp)
  bool help = false;
};

PreviewOptions parse_options(int argc, char** argv);
extern const char* const kPreviewUsage;

}  // namespace preview
