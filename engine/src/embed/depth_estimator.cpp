// dvs/depth_frames.hpp: Video-Depth-Anything loaded once on a dvs::Context, run on frames the application hands
// over. The estimate itself is estimate_depth's (pipeline/frames_depth.hpp), so the disparity equals `dvs depth`'s
// for the same frames. The estimator holds its context's core (embed/context_core.hpp) and takes its turn at the
// context's gate for each call.
#include "dvs/depth_frames.hpp"

#include <cstring>
#include <optional>

#include "dvs/error.hpp"
#include "embed/context_core.hpp"
#include "embed/device_copy.hpp"
#include "embed/public_call.hpp"
#include "embed/view_facts.hpp"
#include "models/vda/vda_model.hpp"
#include "pipeline/frames_depth.hpp"

namespace dvs {

struct DepthEstimator::Impl {
  std::shared_ptr<embed::ContextCore> core;  // first: the device objects outlive the model
  FramesDepthOptions options;
  std::optional<VdaModel> model;

  // The estimate of frames in host memory (both public forms), at the context's turn.
  void estimate(const ConstHostView& frames, const HostView& out, const ProgressFn& progress,
                const CancelFn& cancelled);
};

namespace {

constexpr const char* kWhere = "dvs::DepthEstimator::estimate";
constexpr const char* kMake = "dvs::DepthEstimator";

// frames u8 [F,H,W,3] and out f32 [F,H,W], host or device (each view's `missing` says why it is not given).
void check_views(const embed::ViewFacts& frames, const embed::ViewFacts& out) {
  const auto& f = frames.shape;
  auto refuse = [](const std::string& what) { throw Error(std::string(kWhere) + ": " + what, ErrorKind::invalid_argument); };
  if (frames.type != ElementType::u8 || f.size() != 4 || f[3] != 3 || f[0] < 1 || f[1] < 1 || f[2] < 1)
    refuse("frames must be u8 [F,H,W,3] RGB with F, H, W >= 1, got " + frames.text);
  if (!frames.given) refuse(frames.missing + " (give the frames' memory)");
  const std::vector<int64_t> want{f[0], f[1], f[2]};
  if (out.type != ElementType::f32 || out.shape != want)
    refuse("out must be f32 [" + std::to_string(f[0]) + "x" + std::to_string(f[1]) + "x" + std::to_string(f[2]) +
           "] (the frames' F, H, W), got " + out.text);
  if (!out.given) refuse(out.missing + " (give memory for the disparity)");
}

void check_views(const ConstHostView& frames, const HostView& out) {
  check_views(embed::facts("frames", frames, "frames.data is null"), embed::facts("out", out, "out.data is null"));
}

void check_views(vk::Context& ctx, const DeviceBufferView& frames, const DeviceBufferView& out) {
  check_views(embed::facts("frames", frames, "the frames' buffer is VK_NULL_HANDLE"),
              embed::facts("out", out, "the output buffer is VK_NULL_HANDLE"));
  embed::check_view_fits(ctx, frames, frames.type, frames.shape, std::string(kWhere) + "'s frames");
  embed::check_view_fits(ctx, out, out.type, out.shape, std::string(kWhere) + "'s out");
}

}  // namespace

DepthEstimator::DepthEstimator(Context& ctx, const std::filesystem::path& model, const DepthModelOptions& options) {
  const std::shared_ptr<embed::ContextCore> core = ctx.core();
  impl_ = embed::public_call(kMake, [&] {
    if (!std::filesystem::is_regular_file(model))
      throw Error(model.string() + ": no such depth model (give a video_depth_anything_vit{s,b,l}.pth or a "
                  ".safetensors of it; README.md says where the checkpoints are)");
    if (options.input_size < 14 || options.input_size > 4096)
      throw Error("dvs::DepthModelOptions::input_size must be in [14, 4096] (the model's default is 518), got " +
                      std::to_string(options.input_size),
                  ErrorKind::invalid_argument);
    auto impl = std::make_unique<Impl>();
    impl->core = core;
    impl->options.input_size = options.input_size;
    impl->options.input_size_option = "DepthModelOptions::input_size";
    impl->options.model_file = model;
    VdaModel::inspect(model);  // another model's file is named before any upload
    embed::GateUse use(core->gate, kMake);
    impl->model.emplace(VdaModel::load(*core->device, model));
    if (options.metric) impl->model->set_metric(*options.metric);
    return impl;
  });
}

// Under a job on the context, the model's device memory is freed at the job's end (on its thread).
DepthEstimator::~DepthEstimator() {
  if (!impl_) return;
  const std::shared_ptr<embed::ContextCore> core = impl_->core;
  core->gate.destroy_when_free([estimator = std::shared_ptr<Impl>(std::move(impl_))]() mutable { estimator.reset(); });
}

bool DepthEstimator::metric() const { return impl_->model->config().metric; }

void DepthEstimator::estimate(const ConstHostView& frames, const HostView& out, const ProgressFn& progress,
                              const CancelFn& cancelled) {
  Impl& e = *impl_;
  embed::public_call(kWhere, [&] {
    embed::GateUse use(e.core->gate, kWhere);
    e.estimate(frames, out, progress, cancelled);
  });
}

void DepthEstimator::Impl::estimate(const ConstHostView& frames, const HostView& out, const ProgressFn& progress,
                                    const CancelFn& cancelled) {
  check_views(frames, out);
  check_vda_fits(*core->device, model->config(), int(frames.shape[1]), int(frames.shape[2]), options);
  if (cancelled && cancelled()) throw Cancelled();
  HostTensor in(frames.shape, DType::u8);
  std::memcpy(in.data.data(), frames.data, in.bytes());
  DepthSummary summary;
  const HostTensor depth = estimate_frames_depth(*model, in, options, progress, cancelled, summary);
  std::memcpy(out.data, depth.data.data(), depth.bytes());
}

void DepthEstimator::estimate(const DeviceBufferView& frames, const DeviceBufferView& out, const ProgressFn& progress,
                              const CancelFn& cancelled) {
  Impl& e = *impl_;
  embed::public_call(kWhere, [&] {
    embed::GateUse use(e.core->gate, kWhere);
    vk::Context& device = *e.core->device;
    check_views(device, frames, out);
    check_vda_fits(device, e.model->config(), int(frames.shape[1]), int(frames.shape[2]), e.options);
    HostTensor in = embed::fetch_view(device, frames, std::string(kWhere) + "'s frames");
    HostTensor disparity(out.shape, DType::f32);
    e.estimate(ConstHostView{in.data.data(), ElementType::u8, in.shape},
               HostView{disparity.data.data(), ElementType::f32, out.shape}, progress, cancelled);
    device.wait(embed::copy_from_tensor(device, Tensor::upload(device, disparity, "disparity for the application"), out,
                                        std::string(kWhere) + "'s out"));
  });
}

}  // namespace dvs
