// dvs/scene.hpp: PointCloudScene over the splat renderer of `dvs render` (geometry/splat.hpp) for one frame.
// The frame and its depth are uploaded once; every buffer a render needs is made by the constructor (the packed
// RGBA8 image on its first use), so a render allocates nothing. A render records the splat with the pose in push
// constants, and the recording is replayed as it is while the pose and the destination stay the same (a still
// camera costs one submission).
#include "dvs/scene.hpp"

#include <array>
#include <span>

#include "dvs/error.hpp"
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


// What a recording renders and where its result goes: the same key replays the recording.
struct RecordingKey {
  std::array<double, 16> pose{};
  embed::SceneImage image = embed::SceneImage::planar_f32;
  bool on_device = false;
  VkBuffer image_buffer = VK_NULL_HANDLE, mask_buffer = VK_NULL_HANDLE;
  VkDeviceSize image_offset = 0, mask_offset = 0;
  bool operator==(const RecordingKey&) const = default;
};

struct PackPush {  // shaders/render/pack_rgba8.comp
  uint32_t pixels;
};

}  // namespace

struct PointCloudScene::Impl {
  Impl(Context& c, HostTensor rgb_host, HostTensor depth_host, const geometry::Intrinsics& K_, const SceneOptions& o)
      : ctx(c),
        device(c.internal()),
        H(int(depth_host.shape[1])),
        W(int(depth_host.shape[2])),
        K(K_),
        renderer(device, H, W, 1, splat_options(o)),
        rec(device),
        centre(::dvs::centre_depth(depth_host)) {
    rgb = Tensor::upload(device, rgb_host, "scene frame");
    depth = Tensor::upload(device, depth_host, "scene depth");
    render = Tensor::empty(device, {1, 3, H, W}, DType::f32, "scene render");
    mask = Tensor::empty(device, {1, H, W}, DType::f32, "scene mask");
  }

  // Records (or keeps) the render for `key`; `device_image` / `device_mask` are the application's buffers.
  void prepare(const RecordingKey& key, const glm::dmat4& T, const vk::BufferView& device_image,
               const vk::BufferView& device_mask) {
    if (recorded && key == last) return;
    recorded = false;
    if (key.image == embed::SceneImage::rgba8 && !packed.defined())
      packed = Tensor::empty(device, {H, W, 4}, DType::u8, "scene RGBA8 image");
    rec.begin();
    renderer.record(rec, rgb, depth, std::span<const glm::dmat4>(&T, 1), K, K, render, mask);
    if (key.image == embed::SceneImage::rgba8) {
      const PackPush push{uint32_t(H) * uint32_t(W)};
      const ops::Grid g = ops::grid_1d(device.caps(), int64_t(push.pixels), 64);
      rec.dispatch(device.pipelines().get("render/pack_rgba8"), {render.buffer(), mask.buffer(), packed.buffer()}, &push,
                   sizeof push, g.x, g.y, g.z, "pack_rgba8");
    }
    if (key.on_device) {
      const Tensor& image = key.image == embed::SceneImage::rgba8 ? packed : render;
      rec.copy(image.buffer(), device_image, image.bytes());
      if (device_mask.valid()) rec.copy(mask.buffer(), device_mask, mask.bytes());
    }
    rec.end();
    last = key;
    recorded = true;
  }

  Context& ctx;
  vk::Context& device;
  int H, W;
  geometry::Intrinsics K;
  geometry::SplatRenderer renderer;
  vk::Recorder rec;
  float centre;
  Tensor rgb, depth, render, mask, packed;
  RecordingKey last;
  bool recorded = false;
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
  const glm::dmat4 T = embed::pose_matrix(pose);
  RecordingKey key;
  key.pose = pose.m;
  key.image = embed::host_image_kind(image, s.H, s.W);
  const bool want_mask = embed::host_mask_wanted(mask, s.H, s.W);
  s.prepare(key, T, {}, {});
  s.rec.submit();
  const Tensor& out = key.image == embed::SceneImage::rgba8 ? s.packed : s.render;
  s.device.transfer().download(out.buffer(), image.data, out.bytes());
  if (want_mask) s.device.transfer().download(s.mask.buffer(), mask.data, s.mask.bytes());
}

uint64_t PointCloudScene::render(const Pose& pose, const DeviceBufferView& image, const DeviceBufferView& mask) {
  Impl& s = *impl_;
  const glm::dmat4 T = embed::pose_matrix(pose);
  RecordingKey key;
  key.pose = pose.m;
  key.image = embed::device_image_kind(image, s.H, s.W);
  key.on_device = true;
  key.image_buffer = image.buffer;
  key.image_offset = image.offset;
  vk::BufferView mask_view;
  if (embed::device_mask_wanted(mask, s.H, s.W)) {
    key.mask_buffer = mask.buffer;
    key.mask_offset = mask.offset;
    mask_view = vk::BufferView{mask.buffer, mask.offset, mask.bytes(), nullptr};
  }
  s.prepare(key, T, vk::BufferView{image.buffer, image.offset, image.bytes(), nullptr}, mask_view);
  s.rec.submit();
  return s.ctx.submitted_value();
}

}  // namespace dvs
