// dvs/dvs.h: the point-cloud scene calls over dvs::PointCloudScene. Sizes come as numbers here, so the C layer
// checks them (naming the argument) before it builds the views the C++ call takes.
#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"

using namespace dvs::capi;

extern "C" {

dvs_status dvs_intrinsics_default(int32_t width, int32_t height, int32_t squash, dvs_intrinsics* out) {
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    const char* call = "dvs_intrinsics_default";
    require(out, call, "out");
    check_size(width, call, "width");
    check_size(height, call, "height");
    const dvs::CameraIntrinsics k = dvs::CameraIntrinsics::dvs_default(width, height, squash != 0);
    *out = {k.fx, k.fy, k.cx, k.cy, k.width, k.height};
  });
}

dvs_status dvs_scene_create(dvs_context* context, const void* frame, dvs_element_type frame_type, int32_t height,
                            int32_t width, const float* depth, const dvs_intrinsics* intrinsics,
                            const dvs_scene_options* options, dvs_scene** out) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_scene_create";
    require(out, call, "out");
    *out = nullptr;
    require(context, call, "context");
    require(frame, call, "frame");
    require(depth, call, "depth");
    require(intrinsics, call, "intrinsics");
    check_size(height, call, "height");
    check_size(width, call, "width");
    dvs::HostView f{const_cast<void*>(frame), element_type(frame_type, call, "frame_type"), {}};
    f.shape = f.type == dvs::ElementType::u8 ? std::vector<int64_t>{height, width, 3} : std::vector<int64_t>{3, height, width};
    const dvs::HostView d{const_cast<float*>(depth), dvs::ElementType::f32, {height, width}};
    dvs::CameraIntrinsics k;
    k.fx = intrinsics->fx, k.fy = intrinsics->fy, k.cx = intrinsics->cx, k.cy = intrinsics->cy;
    k.width = intrinsics->width, k.height = intrinsics->height;
    dvs::SceneOptions o;
    if (options) o.depth_is_disparity = options->depth_is_disparity != 0, o.hard_points = options->hard_points != 0;
    auto handle = std::make_unique<dvs_scene>();
    handle->scene = std::make_unique<dvs::PointCloudScene>(*context->context, f, d, k, o);
    *out = handle.release();
  });
}

dvs_status dvs_scene_render(dvs_scene* scene, const double pose[16], void* image, dvs_element_type image_type,
                            float* mask) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_scene_render";
    require(scene, call, "scene");
    require(pose, call, "pose");
    require(image, call, "image");
    const int64_t h = scene->scene->height(), w = scene->scene->width();
    dvs::HostView img{image, element_type(image_type, call, "image_type"), {}};
    img.shape = scene_image_shape(img.type, h, w);
    dvs::HostView m;
    if (mask) m = {mask, dvs::ElementType::f32, {h, w}};
    scene->scene->render(pose_of(pose), img, m);
  });
}

dvs_status dvs_scene_orbit_radius(const dvs_scene* scene, double* out) {
  return guarded(DVS_ERROR_FILE, [&] {
    require(scene, "dvs_scene_orbit_radius", "scene");
    require(out, "dvs_scene_orbit_radius", "out");
    *out = scene->scene->orbit_radius();
  });
}

dvs_status dvs_scene_destroy(dvs_scene* scene) {
  return guarded(DVS_ERROR_DEVICE, [&] { delete scene; });
}

}  // extern "C"
