// Copies from a dvs Tensor into an application's 2-D VkImage (dvs::DeviceImageView) on the same device: one
// buffer→image copy with the image's layout transitions around it, recorded into the caller's command buffer. The
// first barrier moves the image from the application's `layout` (after everything the application submitted
// before, on this queue or ordered by wait_before_next) to TRANSFER_DST_OPTIMAL; the last moves it to `final_layout`
// and makes the copy's writes visible to every later use on the device, which the application orders by waiting
// for the ticket on the context's timeline. Same family or CONCURRENT sharing: no ownership transfer.
#pragma once
#include <vulkan/vulkan.h>

#include <string>

#include "dvs/views.hpp"
#include "tensor/tensor.hpp"

namespace dvs::embed {

// What a tensor becomes in an image: RGBA8 bytes [H,W,4] → R8G8B8A8_UNORM, f32 [H,W] → R32_SFLOAT.
enum class ImageTexels { rgba8, r32f };

// Throws dvs::Error naming `what` ("PointCloudScene's image") when `view` cannot take `texels` at height × width:
// no image, another format (an _SRGB format says why it is refused), another size, or a final layout an image
// cannot be left in (UNDEFINED, PREINITIALIZED) or a start layout it cannot be in.
void check_image_fits(const DeviceImageView& view, ImageTexels texels, int height, int width, const std::string& what);

// Record the copy of `from` (the texels of the whole image, row-major, tightly packed) into `to`, with the layout
// transitions; check_image_fits first.
void record_copy_to_image(VkCommandBuffer cmd, const Tensor& from, const DeviceImageView& to);

}  // namespace dvs::embed
