#include "pipeline/depth_forecast.hpp"

#include <algorithm>
#include <cstdio>

#include "io/option_names.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_preprocess.hpp"
#include "dvs/duration_text.hpp"

namespace dvs {
namespace {

std::string flops_text(double f) {
  char buf[32];
  if (f >= 1e12) std::snprintf(buf, sizeof buf, "%.1f TFLOP", f / 1e12);
  else std::snprintf(buf, sizeof buf, "%.1f GFLOP", f / 1e9);
  return buf;
}

}  // namespace

DepthForecast::DepthForecast(DepthForecastInput in) : in_(std::move(in)) {
  chunk_frames_ = std::min<int64_t>(VdaModel::kEncoderChunkFrames, in_.cfg.infer_len);
  // The first block also compiles and uploads what the rest reuse: the rate comes from the blocks after it.
  measure_step_ = std::min(in_.cfg.depth, 3);
}

double DepthForecast::seconds_for(int input_size, int windows) const {
  const VdaInputSize s = vda_input_size(in_.frame_height, in_.frame_width, input_size, in_.cfg.patch_size);
  return windows * vda_window_flops(in_.cfg, in_.cfg.infer_len, s.height, s.width).window() / rate_;
}

std::optional<std::string> DepthForecast::on_step(const VdaStep& step, double seconds) {
  if (step.window != 1 || rate_ > 0) return std::nullopt;
  const VdaInputSize s = vda_input_size(in_.frame_height, in_.frame_width, in_.input_size, in_.cfg.patch_size);
  const VdaFlops f = vda_window_flops(in_.cfg, in_.cfg.infer_len, s.height, s.width);
  const double block = f.encoder_block * double(chunk_frames_);
  if (step.done == 1) first_step_s_ = seconds;
  if (step.done < measure_step_) return std::nullopt;
  rate_ = measure_step_ > 1 ? (measure_step_ - 1) * block / std::max(1e-6, seconds - first_step_s_) : block / std::max(1e-6, seconds);
  expected_s_ = seconds_for(in_.input_size, in_.windows);
  if (said_ || expected_s_ < in_.threshold_s) return std::nullopt;
  said_ = true;
  char rate[32];
  std::snprintf(rate, sizeof rate, "%.1f GFLOP/s", rate_ / 1e9);
  std::string m = "this depth estimate will take about " + duration_text(expected_s_) + " on this device (" +
                  flops_text(in_.windows * f.window()) + ": " + count_text(in_.windows, "window", "windows") + " of " +
                  std::to_string(in_.cfg.infer_len) + " frames at a " + std::to_string(s.height) + "x" +
                  std::to_string(s.width) + " network input; " + rate + " measured on the first frames). Cheaper:";
  const int smaller = std::max(in_.cfg.patch_size, in_.input_size / 2 / in_.cfg.patch_size * in_.cfg.patch_size);
  bool any = false;
  if (smaller < in_.input_size) {
    m += " " + in_.input_size_option + " " + std::to_string(smaller) + " (about " + duration_text(seconds_for(smaller, in_.windows)) +
         ", coarser depth)";
    any = true;
  }
  if (in_.windows > 1) {
    m += std::string(any ? ";" : "") + " " + in_.frames_option + " " + std::to_string(in_.cfg.infer_len) + " (1 window, about " +
         duration_text(seconds_for(in_.input_size, 1)) + ")";
    any = true;
  }
  if (!any) m += " a faster device (" + option_name("DepthJob::device") + ")";
  return m + in_words_of_caller(". Ctrl-C stops it.", ". The cancel function stops it.");
}

}  // namespace dvs
