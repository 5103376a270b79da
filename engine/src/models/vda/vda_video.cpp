#include "models/vda/vda_video.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include "dvs/error.hpp"
#include "models/vda/vda_stitch.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_resize.hpp"

namespace dvs {
namespace {

// A window's disparity at the frame size: finite and not one value everywhere, else the model is broken.
void check_window(const HostTensor& disparity, size_t window, size_t windows, const std::vector<int64_t>& frames) {
  const float* v = disparity.as<float>();
  const int64_t n = disparity.numel();
  const std::string where = "depth window " + std::to_string(window + 1) + "/" + std::to_string(windows) + " (clip frames " +
                            std::to_string(frames.front() + 1) + "-" + std::to_string(frames.back() + 1) + ")";
  for (int64_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i]))
      throw VdaBrokenOutput(where + ": the model's disparity holds " + (std::isnan(v[i]) ? "NaN" : "an infinite value") +
                  " (first at element " + std::to_string(i) + ")");
  if (n > 1 && std::all_of(v, v + n, [&](float x) { return x == v[0]; }))
    throw VdaBrokenOutput(where + ": the model's disparity is " + std::to_string(v[0]) +
                " everywhere; NaN weights give this after the final ReLU");
}

}  // namespace

VdaVideoResult vda_video_depth(VdaModel& model, const HostTensor& frames, const VdaVideoOptions& o) {
  const Shape& s = frames.shape;
  if (frames.dtype != DType::u8 || s.size() != 4 || s[3] != 3 || s[0] < 1)
    throw Error("internal: vda_video_depth takes u8 RGB frames [L, H, W, 3], got " + std::string(dtype_name(frames.dtype)) +
                " [" + shape_str(s) + "]");
  const VdaConfig& cfg = model.config();
  const int64_t L = s[0], H = s[1], W = s[2];
  VdaVideoResult result;
  result.input = vda_input_size(H, W, o.input_size, cfg.patch_size);
  const int64_t h = result.input.height, w = result.input.width, plane = 3 * h * w;
  const auto windows = vda_window_frames(L, cfg);

  // Preprocessed frames by clip index, kept while a later window may still use them.
  std::map<int64_t, std::vector<float>> ready;
  auto input_of = [&](int64_t f) -> const std::vector<float>& {
    auto it = ready.find(f);
    if (it == ready.end()) {
      it = ready.emplace(f, std::vector<float>(size_t(plane))).first;
      vda_preprocess_frame(frames.as<uint8_t>() + f * H * W * 3, H, W, result.input, cfg, it->second.data());
    }
    return it->second;
  };

  vk::Context& ctx = model.context();
  VdaStitcher stitcher(cfg, H * W);
  // The model reports the steps of each forward; the hook is the model's only while this runs.
  struct HookGuard {
    VdaModel& m;
    ~HookGuard() { m.set_step_hook({}); }
  } guard{model};
  size_t window = 0;
  if (o.on_step)
    model.set_step_hook([&](const std::string& what, int done, int total) {
      o.on_step(VdaStep{int(window) + 1, int(windows.size()), done, total, what});
    });
  for (size_t k = 0; k < windows.size(); ++k) {
    window = k;
    const auto& idx = windows[k];
    HostTensor x({int64_t(idx.size()), 3, h, w}, DType::f32);
    for (size_t i = 0; i < idx.size(); ++i) {
      const auto& f = input_of(idx[i]);
      std::copy(f.begin(), f.end(), x.as<float>() + int64_t(i) * plane);
    }
    // Forget the frames no later window reads: the next one takes this window's key frames, then frames from
    // its own start on.
    if (k + 1 < windows.size()) {
      const int64_t next_start = int64_t(k + 1) * (cfg.infer_len - cfg.overlap);
      std::set<int64_t> needed;
      for (int kf : cfg.keyframes) needed.insert(idx[size_t(kf)]);
      std::erase_if(ready, [&](const auto& e) { return e.first < next_start && !needed.count(e.first); });
    }
    const Tensor depth = model.forward(Tensor::upload(ctx, x, "depth window input"));  // [T, h, w]
    const int64_t T = depth.dim(0);
    const Tensor full = Tensor::empty(ctx, {T, 1, H, W}, DType::f32, "depth window at frame size");
    ops::run_now(ctx, [&](vk::Recorder& r) { ops::resize_bilinear(r, depth.reshape({T, 1, h, w}), full, true); });
    HostTensor up = full.download(ctx);
    up.shape = {T, H, W};
    check_window(up, k, windows.size(), idx);
    if (o.probe) o.probe(int(k), idx, depth.download(ctx), up);
    std::vector<std::vector<float>> per_frame(static_cast<size_t>(T));
    const float* u = up.as<float>();
    for (int64_t t = 0; t < T; ++t) per_frame[size_t(t)].assign(u + t * H * W, u + (t + 1) * H * W);
    stitcher.add_window(std::move(per_frame));
    if (o.on_window) o.on_window(int(k) + 1, int(windows.size()));
  }
  result.depth = stitcher.finish(L, H, W);
  result.scale_shift = stitcher.scale_shift();
  return result;
}

}  // namespace dvs
