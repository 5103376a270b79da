#include "pipeline/frames_depth.hpp"

#include <chrono>

#include "dvs/error.hpp"
#include "io/crash_points.hpp"
#include "models/vda/vda_memory.hpp"
#include "models/vda/vda_stitch.hpp"
#include "models/vda/vda_video.hpp"
#include "pipeline/depth_forecast.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

void check_vda_fits(vk::Context& ctx, const VdaConfig& cfg, int height, int width, const FramesDepthOptions& o) {
  // An estimate whose tensors cannot be allocated on this device is refused before the work, with the network
  // input that fits (the figures dvs plan and run's preflight use).
  const vk::DeviceCaps& caps = ctx.caps();
  if (const std::string p = vda_fit_problem(cfg, height, width, o.input_size, caps.max_memory_allocation_size,
                                            std::nullopt, ctx.allocator().alignment(),
                                            "device " + caps.name + (caps.forced_limits.any() ? " lowered by DVS_LIMITS" : ""),
                                            o.input_size_option);
      !p.empty())
    throw Error(p);
}

HostTensor estimate_frames_depth(VdaModel& model, const HostTensor& frames, const FramesDepthOptions& opt,
                                 const ProgressFn& progress, const CancelFn& cancelled, DepthSummary& s) {
  const auto t = std::chrono::steady_clock::now();
  const int frame_count = int(frames.shape[0]);
  s.windows = int(vda_window_frames(frame_count, model.config()).size());
  DepthForecastInput fi;
  fi.cfg = model.config();
  fi.frame_height = int(frames.shape[1]), fi.frame_width = int(frames.shape[2]);
  fi.input_size = opt.input_size;
  fi.windows = s.windows;
  fi.input_size_option = opt.input_size_option;
  fi.frames_option = opt.frames_option;
  fi.threshold_s = opt.forecast_after_s;
  DepthForecast forecast(fi);
  VdaVideoOptions o;
  o.input_size = opt.input_size;
  o.on_step = [&](const VdaStep& st) {
    // Cancellation first: a step can take seconds on a CPU device, and Ctrl-C must not wait for a window.
    if (cancelled && cancelled()) throw Cancelled();
    crash_point("step", "depth", (st.window - 1) * st.total + st.done);
    if (auto m = forecast.on_step(st, seconds_since(t))) {
      if (opt.notice) opt.notice(*m);
      else if (progress) progress("depth", 0, 0, *m);
    }
    if (progress)
      progress("depth", (st.window - 1) * st.total + st.done, st.windows * st.total,
               (st.windows > 1 ? "window " + std::to_string(st.window) + "/" + std::to_string(st.windows) + ": " : "") + st.what);
  };
  VdaVideoResult r;
  try {
    r = vda_video_depth(model, frames, o);
  } catch (const VdaBrokenOutput& e) {
    const std::string file = opt.model_file.string();
    throw Error(file + ": " + e.what() + "; the estimate is refused, not cached. Usual causes: weights "
                "holding NaN/Inf (dvs-weights inspect --values " + file + " lists them) or a damaged file");
  }
  s.input_height = int(r.input.height), s.input_width = int(r.input.width);
  s.seconds_depth = seconds_since(t);
  s.peak_device_bytes = model.context().allocator().stats().peak_bytes_reserved;
  return std::move(r.depth);
}

}  // namespace dvs
