// Video-Depth-Anything on decoded frames already in memory, with a loaded model: the one code path behind
// estimate_depth (frames decoded from a file) and dvs::DepthEstimator (frames the application hands over), so
// both give the same disparity for the same frames, with the same progress, forecast and cancellation.
#pragma once
#include <filesystem>
#include <functional>
#include <string>

#include "dvs/depth_estimate.hpp"
#include "io/host_tensor.hpp"
#include "models/vda/vda_model.hpp"

namespace dvs {

struct FramesDepthOptions {
  int input_size = 518;                            // the network input's short side
  std::string input_size_option, frames_option;    // how messages name them (DepthJob's)
  std::filesystem::path model_file;                // named by the error of a broken estimate
  double forecast_after_s = 60;                    // see DepthJob::forecast_after_s
  // Lines kept apart from the progress (the forecast); unset: progress notes of stage "depth".
  std::function<void(const std::string&)> notice;
};

// Refuses (dvs::Error with the input size that fits) an estimate whose tensors cannot be allocated on the
// model's device: frames height x width at options.input_size. Cheap; called before the model loads where it can.
void check_vda_fits(vk::Context& ctx, const VdaConfig& cfg, int height, int width, const FramesDepthOptions& options);

// frames: u8 [F, H, W, 3] RGB. Returns disparity f32 [F, H, W] (metric depth for a metric model) and fills the
// summary's windows, network input size, seconds_depth and peak_device_bytes. Progress: stage "depth", steps
// within every window; `cancelled` is polled at every step (dvs::Cancelled).
HostTensor estimate_frames_depth(VdaModel& model, const HostTensor& frames, const FramesDepthOptions& options,
                                 const ProgressFn& progress, const CancelFn& cancelled, DepthSummary& summary);

}  // namespace dvs
