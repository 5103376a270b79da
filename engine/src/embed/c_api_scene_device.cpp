// dvs/dvs.h: the device-memory calls — scene renders into the application's buffers and images, and the context
// calls that order dvs's work with the application's (its timeline's last value, waiting for the application's
// semaphore). Handles and sizes are checked here, naming the argument, before the C++ views are built.
#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"

using namespace dvs::capi;

namespace {

dvs::DeviceImageView image_view(const dvs_device_image& i) {
  dvs::DeviceImageView v;
  v.image = i.image;
  v.format = i.format;
  v.width = i.width;
  v.height = i.height;
  v.layout = i.layout;
  v.final_layout = i.final_layout;
  return v;
}

}  // namespace

extern "C" {

dvs_status dvs_scene_render_to_buffers(dvs_scene* scene, const double pose[16], VkBuffer image,
                                       VkDeviceSize image_offset, dvs_element_type image_type, VkBuffer mask,
                                       VkDeviceSize mask_offset, uint64_t* ticket) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_scene_render_to_buffers";
    require(ticket, call, "ticket");
    require(scene, call, "scene");
    require(pose, call, "pose");
    if (!image) throw dvs::UsageError(std::string(call) + ": image is VK_NULL_HANDLE (pass a VkBuffer of the context's device)");
    const int64_t h = scene->scene->height(), w = scene->scene->width();
    dvs::DeviceBufferView img{image, image_offset, element_type(image_type, call, "image_type"), {}};
    img.shape = scene_image_shape(img.type, h, w);
    dvs::DeviceBufferView m;
    if (mask) m = {mask, mask_offset, dvs::ElementType::f32, {h, w}};
    *ticket = scene->scene->render(pose_of(pose), img, m);
  });
}

dvs_status dvs_scene_render_to_images(dvs_scene* scene, const double pose[16], const dvs_device_image* image,
                                      const dvs_device_image* mask, uint64_t* ticket) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_scene_render_to_images";
    require(ticket, call, "ticket");
    require(scene, call, "scene");
    require(pose, call, "pose");
    require(image, call, "image");
    *ticket = scene->scene->render(pose_of(pose), image_view(*image), mask ? image_view(*mask) : dvs::DeviceImageView{});
  });
}

dvs_status dvs_context_submitted_value(const dvs_context* context, uint64_t* out) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    require(context, "dvs_context_submitted_value", "context");
    require(out, "dvs_context_submitted_value", "out");
    *out = context->context->submitted_value();
  });
}

dvs_status dvs_context_wait_before_next(dvs_context* context, VkSemaphore semaphore, uint64_t value) {
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    require(context, "dvs_context_wait_before_next", "context");
    context->context->wait_before_next(semaphore, value);
  });
}

}  // extern "C"
