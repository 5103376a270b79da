// Video-Depth-Anything on frames in memory: a window of frames in, disparity out, no files. The network and its
// weights stay loaded between calls. The same estimate as `dvs depth` for the same frames.
#pragma once
#include <filesystem>
#include <memory>
#include <optional>

#include "dvs/api.hpp"
#include "dvs/context.hpp"
#include "dvs/pipeline.hpp"
#include "dvs/views.hpp"

namespace dvs {

struct DepthModelOptions {
  int input_size = 518;        // the network input's short side (run.py --input_size)
  std::optional<bool> metric;  // unset: the checkpoint's mode (metric_* files are metric)
};

class DVS_API DepthEstimator {
 public:
  // model: video_depth_anything_vit{s,b,l}.pth (or metric_...) or a .safetensors of it. Throws dvs::Error naming
  // the file at fault.
  DepthEstimator(Context& ctx, const std::filesystem::path& model, const DepthModelOptions& options = {});
  ~DepthEstimator();
  DepthEstimator(const DepthEstimator&) = delete;
  DepthEstimator& operator=(const DepthEstimator&) = delete;

  bool metric() const;
  // frames: u8 [F,H,W,3] RGB; out: f32 [F,H,W], disparity (metric depth for a metric model) at the frames' size.
  // Progress and cancellation as estimate_depth (stage "depth").
  void estimate(const ConstHostView& frames, const HostView& out, const ProgressFn& progress = {},
                const CancelFn& cancelled = {});
  // The same with the frames in, and the disparity out to, the application's device buffers (dvs/views.hpp; a
  // HostDevice context). The frames are copied in at the start (the network's input resize runs on the host); the
  // call returns once the disparity is in `out`. Types, shapes, offsets and ranges are checked before any work.
  void estimate(const DeviceBufferView& frames, const DeviceBufferView& out, const ProgressFn& progress = {},
                const CancelFn& cancelled = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dvs
