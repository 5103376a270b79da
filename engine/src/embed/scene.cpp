// dvs/scene.hpp: PointCloudScene over the splat renderer of `dvs render` (geometry/splat.hpp) for one frame.
// The frame and its depth are uploaded once; every buffer a render needs is made by the constructor (the packed
// RGBA8 image on its first use), so a render allocates nothing. A render records the splat with the pose in push
// constants and submits it, then packs it into RGBA8 when asked (a recording of its own, made once) and downloads
// it or copies it into the application's buffers. A pose equal to the last one
// skips the splat: its result is still in the scene's buffers (a still camera costs a download).
#include "dvs/scene.hpp"

#include <array>
#include <span>

#include "dvs/error.hpp"
#include "embed/device_copy.hpp"
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
};

}  // namespace

struct PointCloudScene::Impl {
  Impl(Context& c, HostTensor rgb_host, HostTensor depth_host, const geometry::Intrinsics& K_, const SceneOptions& o)
      : device(c.internal()),
        H(int(depth_host.shape[1])),
        W(int(depth_host.shape[2])),
        K(K_),
        renderer(device, H, W, 1, splat_options(o)),
        splat_rec(device),
        pack_rec(device),
        centre(::dvs::centre_depth(depth_host)) {
    rgb = Tensor::upload(device, rgb_host, "scene frame");
    depth = Tensor::upload(device, depth_host, "scene depth");
    render = Tensor::empty(device, {1, 3, H, W}, DType::f32, "scene render");
    mask = Tensor::empty(device, {1, H, W}, DType::f32, "scene mask");
  }

  // The splat for `pose` into render and mask: skipped when they already hold it (a still camera).
  void splat(const Pose& pose) {
    if (splatted && pose.m == splat_pose) return;
    const glm::dmat4 T = embed::pose_matrix(pose);
    splatted = false;
    splat_rec.begin();
    renderer.record(splat_rec, rgb, depth, std::span<const glm::dmat4>(&T, 1), K, K, render, mask);
    splat_rec.end();
    splat_rec.submit();
    splat_pose = pose.m;
    splatted = true;
  }

  // The RGBA8 image, made on its first use.
  const Tensor& packed_image() {
    if (!packed.defined()) packed = Tensor::empty(device, {H, W, 4}, DType::u8, "scene RGBA8 image");
    return packed;
  }

  // The render packed into RGBA8 (packed_image), submitted and waited for; the recording is made once.
  void pack() {
    packed_image();
    if (!packing_recorded) {
      const PackPush push{uint32_t(H) * uint32_t(W)};
      const ops::Grid g = ops::grid_1d(device.caps(), int64_t(push.pixels), 64);
      pack_rec.begin();
      pack_rec.dispatch(device.pipelines().get("render/pack_rgba8"), {render.buffer(), mask.buffer(), packed.buffer()},
                        &push, sizeof push, g.x, g.y, g.z, "pack_rgba8");
      pack_rec.end();
      packing_recorded = true;
    }
    pack_rec.submit();
  }

  vk::Context& device;
  int H, W;
  geometry::Intrinsics K;
  geometry::SplatRenderer renderer;
  vk::Recorder splat_rec, pack_rec;
  float centre;
  Tensor rgb, depth, render, mask, packed;
  std::array<double, 16> splat_pose{};
  bool splatted = false;
  bool packing_recorded = false;
};

PointCloudScene::PointCloudScene(Context& ctx, const HostView& frame, const HostView& depth,
                                 const CameraIntrinsics& intrinsics, const SceneOptions& options) {
  HostTensor rgb = embed::scene_frame(frame);
  const int H = int(rgb.shape[2]), W = int(rgb.shape[3]);
  const geometry::Intrinsics K = embed::scene_intrinsics(intrinsics, H, W);
  HostTensor z = embed::scene_depth(depth, H, W, options.depth_is_disparity ? DepthValues::disparity : DepthValues::depth);
  impl_ = std::make_unique<Impl>(ctx, std::move(rgb), std::move(z), K, options);
}

PointCloudScene::~PointCloudScene() = default;

int PointCloudScene::width() const { return impl_->W; }
int PointCloudScene::height() const { return impl_->H; }
double PointCloudScene::orbit_radius() const { return geometry::official_radius(impl_->centre); }
double PointCloudScene::centre_depth() const { return impl_->centre; }

void PointCloudScene::render(const Pose& pose, const HostView& image, const HostView& mask) {
  Impl& s = *impl_;
  const embed::SceneImage kind = embed::host_image_kind(image, s.H, s.W);
  const bool want_mask = embed::host_mask_wanted(mask, s.H, s.W);
  s.splat(pose);
  if (kind == embed::SceneImage::rgba8) s.pack();
  const Tensor& out = kind == embed::SceneImage::rgba8 ? s.packed : s.render;
  s.device.transfer().download(out.buffer(), image.data, out.bytes());
  if (want_mask) s.device.transfer().download(s.mask.buffer(), mask.data, s.mask.bytes());
}

// The splat (and the packing) are waited for; the copies into the application's buffers are not (embed/device_copy:
// they carry the barriers towards the application's use), and the ticket is the last copy's.
uint64_t PointCloudScene::render(const Pose& pose, const DeviceBufferView& image, const DeviceBufferView& mask) {
  Impl& s = *impl_;
  const embed::SceneImage kind = embed::device_image_kind(image, s.H, s.W);
  const bool want_mask = embed::device_mask_wanted(mask, s.H, s.W);
  const Tensor result = kind == embed::SceneImage::rgba8 ? s.packed_image() : s.render.reshape({3, s.H, s.W});
  const Tensor visible = s.mask.reshape({s.H, s.W});
  embed::check_view_fits(s.device, image, result, "PointCloudScene's image");
  if (want_mask) embed::check_view_fits(s.device, mask, visible, "PointCloudScene's mask");
  s.splat(pose);
  if (kind == embed::SceneImage::rgba8) s.pack();
  uint64_t ticket = embed::copy_from_tensor(s.device, result, image, "PointCloudScene's image");
  if (want_mask) ticket = embed::copy_from_tensor(s.device, visible, mask, "PointCloudScene's mask");
  return ticket;
}

}  // namespace dvs
