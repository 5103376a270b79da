// dvs/scene.hpp: PointCloudScene over the splat renderer of `dvs render` (geometry/splat.hpp) for one frame.
// The frame and its depth are uploaded once; every buffer a render needs is made by the constructor (the packed
// RGBA8 image on its first use), so a render allocates nothing. A render records the splat with the pose in push
// constants and submits it, then packs it into RGBA8 when asked (a recording of its own, made once) and downloads
// it or copies it into the application's buffers or images. A pose equal to the last one skips the splat: its
// result is still in the scene's buffers (a still camera costs a download).
//
// Renders into the application's device memory wait for nothing: splat, pack and copies are submitted one after
// the other on the context's queue (each later one's barriers order it after the earlier ones) and the last
// ticket is returned. The next render of the scene waits on the host for that ticket before it resubmits the
// recordings or overwrites the scene's buffers (usually long reached: a frame later), as does the destructor.
//
// The scene holds its context's core (embed/context_core.hpp): it outlives the dvs::Context, and each call takes its
// turn at the context's gate (a destructor under a job is deferred to the job's end).
#include "dvs/scene.hpp"

#include <array>
#include <span>

#include "dvs/error.hpp"
#include "embed/context_core.hpp"
#include "embed/device_copy.hpp"
#include "embed/device_image_copy.hpp"
#include "embed/public_call.hpp"
#include "embed/scene_camera.hpp"
#include "embed/scene_views.hpp"
#include "geometry/splat.hpp"
#include "geometry/trajectory.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"
#include "vk/transfer.hpp"

namespace dvs {

namespace {

geometry::SplatOptions splat_options(const SceneOptions& o) {
  geometry::SplatOptions s;
  s.mode = o.hard_points ? geometry::SplatMode::hard_point : geometry::SplatMode::soft_bilinear;
  return s;
}

struct PackPush {  // shaders/render/pack_rgba8.comp
  uint32_t pixels;
  uint32_t mask_only;
};

// One RGBA8 packing of the scene's render (the colour image) or of its mask alone (a white/black display image):
// its output and its recording, both made on first use.
struct Packing {
  explicit Packing(vk::Context& device, bool mask_only_) : rec(device), mask_only(mask_only_) {}
  vk::Recorder rec;
  Tensor out;
  bool mask_only;
  bool recorded = false;
};

}  // namespace

struct PointCloudScene::Impl {
  Impl(std::shared_ptr<embed::ContextCore> core_, HostTensor rgb_host, HostTensor depth_host,
       const geometry::Intrinsics& K_, const SceneOptions& o)
      : core(std::move(core_)),
        device(*core->device),
        H(int(depth_host.shape[1])),
        W(int(depth_host.shape[2])),
        K(K_),
        renderer(device, H, W, 1, splat_options(o)),
        splat_rec(device),
        colour_packing(device, false),
        mask_packing(device, true),
        centre(::dvs::centre_depth(depth_host)) {
    rgb = Tensor::upload(device, rgb_host, "scene frame");
    depth = Tensor::upload(device, depth_host, "scene depth");
    render = Tensor::empty(device, {1, 3, H, W}, DType::f32, "scene render");
    mask = Tensor::empty(device, {1, H, W}, DType::f32, "scene mask");
  }

  ~Impl() {
    try {
      settle();
    } catch (...) {  // a lost device: nothing left to wait for
    }
  }

  // Waits (on the host) for the previous render's submissions, once: before the recordings are submitted again or
  // the scene's buffers are overwritten.
  void settle() {
    if (pending) device.wait(pending);
    pending = 0;
  }

  // How a recording is submitted: waited for (host renders) or not (device renders, whose ticket is kept).
  void submit(vk::Recorder& rec, bool wait) {
    if (wait)
      rec.submit();
    else
      pending = rec.submit_without_wait();
  }

  // The splat for `pose` into render and mask: skipped when they already hold it (a still camera).
  void splat(const Pose& pose, bool wait) {
    if (splatted && pose.m == splat_pose) return;
    const glm::dmat4 T = embed::pose_matrix(pose);
    splatted = false;
    splat_rec.begin();
    renderer.record(splat_rec, rgb, depth, std::span<const glm::dmat4>(&T, 1), K, K, render, mask);
    splat_rec.end();
    submit(splat_rec, wait);
    splat_pose = pose.m;
    splatted = true;
  }

  // The RGBA8 image of `p` (colour_packing: the render; mask_packing: the mask), made on its first use.
  const Tensor& packed_image(Packing& p) {
    if (!p.out.defined())
      p.out = Tensor::empty(device, {H, W, 4}, DType::u8, p.mask_only ? "scene RGBA8 mask" : "scene RGBA8 image");
    return p.out;
  }
  const Tensor& packed_image() { return packed_image(colour_packing); }

  // The render (or the mask) packed into RGBA8; the recording is made once.
  void pack(Packing& p, bool wait) {
    packed_image(p);
    if (!p.recorded) {
      const PackPush push{uint32_t(H) * uint32_t(W), p.mask_only ? 1u : 0u};
      const ops::Grid g = ops::grid_1d(device.caps(), int64_t(push.pixels), 64);
      p.rec.begin();
      p.rec.dispatch(device.pipelines().get("render/pack_rgba8"), {render.buffer(), mask.buffer(), p.out.buffer()},
                     &push, sizeof push, g.x, g.y, g.z, "pack_rgba8");
      p.rec.end();
      p.recorded = true;
    }
    submit(p.rec, wait);
  }
  void pack(bool wait) { pack(colour_packing, wait); }

  // One command buffer of copies into the application's memory, submitted without a wait; its ticket is the
  // render's.
  uint64_t submit_copies(const std::function<void(VkCommandBuffer)>& record) {
    pending = embed::submit_recorded(device, record);
    return pending;
  }

  // The three renders (PointCloudScene::render), at the context's turn.
  void render_host(const Pose& pose, const HostView& image, const HostView& mask);
  uint64_t render_buffers(const Pose& pose, const DeviceBufferView& image, const DeviceBufferView& mask);
  uint64_t render_images(const Pose& pose, const DeviceImageView& image, const DeviceImageView& mask);

  std::shared_ptr<embed::ContextCore> core;  // first: the device objects outlive everything below
  vk::Context& device;
  int H, W;
  geometry::Intrinsics K;
  geometry::SplatRenderer renderer;
  vk::Recorder splat_rec;
  Packing colour_packing, mask_packing;
  float centre;
  Tensor rgb, depth, render, mask;
  std::array<double, 16> splat_pose{};
  bool splatted = false;
  uint64_t pending = 0;  // the last ticket of a render not waited for (0: none)
};

namespace {

constexpr const char* kMake = "dvs::PointCloudScene";
constexpr const char* kRender = "dvs::PointCloudScene::render";

// A scene's values, converted and checked on the host (before the context's turn).
struct SceneValues {
  HostTensor rgb, depth;
  geometry::Intrinsics K;
};

SceneValues scene_values(const ConstHostView& frame, const ConstHostView& depth, const CameraIntrinsics& intrinsics,
                         const SceneOptions& options) {
  SceneValues v;
  v.rgb = embed::scene_frame(frame);
  const int H = int(v.rgb.shape[2]), W = int(v.rgb.shape[3]);
  v.K = embed::scene_intrinsics(intrinsics, H, W);
  v.depth = embed::scene_depth(depth, H, W, options.depth_is_disparity ? DepthValues::disparity : DepthValues::depth);
  return v;
}

// An input in the application's device buffer brought to the host (copied into a dvs tensor on the device, waited
// for, downloaded), so the device-built scene converts it with the host constructor's own code: bit-identical.
struct FetchedInput {
  HostTensor values;
  ConstHostView view() const {
    return {values.data.data(), values.dtype == DType::u8 ? ElementType::u8 : ElementType::f32, values.shape};
  }
};

FetchedInput fetch(vk::Context& device, const DeviceBufferView& from, const char* arg) {
  bool sized = from.shape.size() == 2 || from.shape.size() == 3;
  for (int64_t d : from.shape) sized = sized && d > 0;
  if (!sized)
    throw Error(std::string("PointCloudScene: ") + arg + ": the device view's shape must have 2 or 3 dimensions, " +
                    "each >= 1 (frame u8 [H,W,3] or f32 [3,H,W], depth f32 [H,W])",
                ErrorKind::invalid_argument);
  return FetchedInput{embed::fetch_view(device, from, std::string("PointCloudScene's ") + arg)};
}

}  // namespace

PointCloudScene::PointCloudScene(Context& ctx, const ConstHostView& frame, const ConstHostView& depth,
                                 const CameraIntrinsics& intrinsics, const SceneOptions& options) {
  const std::shared_ptr<embed::ContextCore> core = ctx.core();
  impl_ = embed::public_call(kMake, [&] {
    SceneValues v = scene_values(frame, depth, intrinsics, options);
    embed::GateUse use(core->gate, kMake);
    return std::make_unique<Impl>(core, std::move(v.rgb), std::move(v.depth), v.K, options);
  });
}

PointCloudScene::PointCloudScene(Context& ctx, const DeviceBufferView& frame, const DeviceBufferView& depth,
                                 const CameraIntrinsics& intrinsics, const SceneOptions& options) {
  const std::shared_ptr<embed::ContextCore> core = ctx.core();
  impl_ = embed::public_call(kMake, [&] {
    embed::GateUse use(core->gate, kMake);
    FetchedInput f = fetch(*core->device, frame, "frame"), d = fetch(*core->device, depth, "depth");
    SceneValues v = scene_values(f.view(), d.view(), intrinsics, options);
    return std::make_unique<Impl>(core, std::move(v.rgb), std::move(v.depth), v.K, options);
  });
}

// Under a job on the context, the scene's device objects are freed at the job's end (on its thread).
PointCloudScene::~PointCloudScene() {
  if (!impl_) return;
  const std::shared_ptr<embed::ContextCore> core = impl_->core;
  core->gate.destroy_when_free([scene = std::shared_ptr<Impl>(std::move(impl_))]() mutable { scene.reset(); });
}

int PointCloudScene::width() const { return impl_->W; }
int PointCloudScene::height() const { return impl_->H; }
double PointCloudScene::orbit_radius() const { return geometry::official_radius(impl_->centre); }
double PointCloudScene::centre_depth() const { return impl_->centre; }

void PointCloudScene::render(const Pose& pose, const HostView& image, const HostView& mask) {
  Impl& s = *impl_;
  embed::public_call(kRender, [&] {
    embed::GateUse use(s.core->gate, kRender);
    s.render_host(pose, image, mask);
  });
}

uint64_t PointCloudScene::render(const Pose& pose, const DeviceBufferView& image, const DeviceBufferView& mask) {
  Impl& s = *impl_;
  return embed::public_call(kRender, [&] {
    embed::GateUse use(s.core->gate, kRender);
    return s.render_buffers(pose, image, mask);
  });
}

uint64_t PointCloudScene::render(const Pose& pose, const DeviceImageView& image, const DeviceImageView& mask) {
  Impl& s = *impl_;
  return embed::public_call(kRender, [&] {
    embed::GateUse use(s.core->gate, kRender);
    return s.render_images(pose, image, mask);
  });
}

void PointCloudScene::Impl::render_host(const Pose& pose, const HostView& image, const HostView& mask) {
  Impl& s = *this;
  const embed::SceneImage kind = embed::host_image_kind(image, s.H, s.W);
  const bool want_mask = embed::host_mask_wanted(mask, s.H, s.W);
  s.settle();
  s.splat(pose, true);
  if (kind == embed::SceneImage::rgba8) s.pack(true);
  const Tensor& out = kind == embed::SceneImage::rgba8 ? s.packed_image() : s.render;
  s.device.transfer().download(out.buffer(), image.data, out.bytes());
  if (want_mask) s.device.transfer().download(s.mask.buffer(), mask.data, s.mask.bytes());
}

// Nothing is waited for but the previous render (settle): the copies carry the barriers towards the application's
// use (embed/device_copy), and the ticket is theirs.
uint64_t PointCloudScene::Impl::render_buffers(const Pose& pose, const DeviceBufferView& image,
                                               const DeviceBufferView& mask) {
  Impl& s = *this;
  const embed::SceneImage kind = embed::device_image_kind(image, s.H, s.W);
  const bool want_mask = embed::device_mask_wanted(mask, s.H, s.W);
  const Tensor result = kind == embed::SceneImage::rgba8 ? s.packed_image() : s.render.reshape({3, s.H, s.W});
  const Tensor visible = s.mask.reshape({s.H, s.W});
  embed::check_view_fits(s.device, image, result, "PointCloudScene's image");
  if (want_mask) embed::check_view_fits(s.device, mask, visible, "PointCloudScene's mask");
  s.settle();
  s.splat(pose, false);
  if (kind == embed::SceneImage::rgba8) s.pack(false);
  return s.submit_copies([&](VkCommandBuffer cmd) {
    embed::record_copy_from_tensor(cmd, result, image);
    if (want_mask) embed::record_copy_from_tensor(cmd, visible, mask);
  });
}

// The same into images: RGBA8 only (a planar f32 render has no image format); the mask as R32_SFLOAT values or as
// an RGBA8 display image (white where visible, black elsewhere).
uint64_t PointCloudScene::Impl::render_images(const Pose& pose, const DeviceImageView& image,
                                              const DeviceImageView& mask) {
  Impl& s = *this;
  embed::check_image_fits(image, embed::ImageTexels::rgba8, s.H, s.W, "PointCloudScene's image");
  const bool want_mask = mask.image != VK_NULL_HANDLE;
  const bool mask_rgba8 = want_mask && mask.format == VK_FORMAT_R8G8B8A8_UNORM;
  // Any other format is refused by check_image_fits as not R32_SFLOAT, the values' own format.
  if (want_mask)
    embed::check_image_fits(mask, mask_rgba8 ? embed::ImageTexels::rgba8 : embed::ImageTexels::r32f, s.H, s.W,
                            "PointCloudScene's mask");
  const Tensor& result = s.packed_image();
  const Tensor& mask_texels = mask_rgba8 ? s.packed_image(s.mask_packing) : s.mask;
  s.settle();
  s.splat(pose, false);
  s.pack(false);
  if (mask_rgba8) s.pack(s.mask_packing, false);
  return s.submit_copies([&](VkCommandBuffer cmd) {
    embed::record_copy_to_image(cmd, result, image);
    if (want_mask) embed::record_copy_to_image(cmd, mask_texels, mask);
  });
}

}  // namespace dvs
