// The preview itself: the input frame's point cloud (dvs::PointCloudScene on dvs::Context made from the window's
// device) rendered every frame from the flown camera, shown as [input frame | render | visibility mask], key
// poses → a path (dvs::interpolate_path) scrubbed, played and exported (dvs::write_trajectory_json / _glb).
#pragma once
#include "preview_options.hpp"

namespace preview {

// Runs until the window closes, Esc, the script's `quit`/end or --frames-to-run; prints the frame times.
// Throws std::runtime_error / dvs::Error with what went wrong.
void run_preview(const PreviewOptions& options);

}  // namespace preview
