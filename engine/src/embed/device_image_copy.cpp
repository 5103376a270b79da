// embed/device_image_copy.hpp: the layout transitions and the buffer→image copy.
#include "embed/device_image_copy.hpp"

#include "dvs/error.hpp"
#include "embed/device_copy.hpp"

namespace dvs::embed {
namespace {

VkImageMemoryBarrier image_barrier(VkImage image, VkImageLayout from, VkImageLayout to, VkAccessFlags src,
                                   VkAccessFlags dst) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = src;
  b.dstAccessMask = dst;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  return b;
}

// Layouts an image can be in when a transfer starts; PREINITIALIZED only for linear images the host wrote, which
// is fine as a start (its contents are discarded by the copy anyway).
bool usable_start(VkImageLayout l) {
  switch (l) {
    case VK_IMAGE_LAYOUT_UNDEFINED:
    case VK_IMAGE_LAYOUT_PREINITIALIZED:
    case VK_IMAGE_LAYOUT_GENERAL:
    case VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL:
    case VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL:
    case VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL:
    case VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL:
    case VK_IMAGE_LAYOUT_PRESENT_SRC_KHR:
      return true;
    default:
      return false;
  }
}

bool usable_final(VkImageLayout l) {
  return l != VK_IMAGE_LAYOUT_UNDEFINED && l != VK_IMAGE_LAYOUT_PREINITIALIZED && usable_start(l);
}

}  // namespace

void check_image_fits(const DeviceImageView& view, ImageTexels texels, int height, int width, const std::string& what) {
  const std::string head = "The device image given for " + what + " (" + view.describe() + ")";
  if (!view.image)
    throw Error(head + " has no VkImage (VK_NULL_HANDLE): pass an image of the context's device.",
                ErrorKind::invalid_argument);
  const VkFormat want = texels == ImageTexels::rgba8 ? VK_FORMAT_R8G8B8A8_UNORM : VK_FORMAT_R32_SFLOAT;
  const char* want_name = texels == ImageTexels::rgba8 ? "VK_FORMAT_R8G8B8A8_UNORM" : "VK_FORMAT_R32_SFLOAT";
  if (view.format == VK_FORMAT_R8G8B8A8_SRGB || view.format == VK_FORMAT_B8G8R8A8_SRGB)
    throw Error(head + " has an sRGB format: dvs writes the render's own 8-bit levels, which an sRGB image would "
                "decode as sRGB when sampled; create it (or a view of it) as " + std::string(want_name) +
                " and convert where the application wants sRGB.", ErrorKind::invalid_argument);
  if (view.format != want)
    throw Error(head + " has the wrong format: it must be " + want_name +
                (texels == ImageTexels::r32f ? " (a mask may also be VK_FORMAT_R8G8B8A8_UNORM: white where visible)" : "") +
                ".", ErrorKind::invalid_argument);
  if (int64_t(view.width) != width || int64_t(view.height) != height)
    throw Error(head + " has the wrong size: it must be " + std::to_string(width) + "x" + std::to_string(height) +
                " (width x height), the scene's.", ErrorKind::invalid_argument);
  if (!usable_start(view.layout))
    throw Error(head + " starts in layout " + std::to_string(int(view.layout)) +
                ", which dvs cannot copy from: give UNDEFINED, GENERAL, a transfer layout, SHADER_READ_ONLY_OPTIMAL, "
                "COLOR_ATTACHMENT_OPTIMAL or PRESENT_SRC_KHR.", ErrorKind::invalid_argument);
  if (!usable_final(view.final_layout))
    throw Error(head + " has final_layout " + std::to_string(int(view.final_layout)) +
                ", which an image cannot be left in (UNDEFINED and PREINITIALIZED are start layouts only): give the "
                "layout the application uses next, e.g. SHADER_READ_ONLY_OPTIMAL or TRANSFER_SRC_OPTIMAL.",
                ErrorKind::invalid_argument);
}

void record_copy_to_image(VkCommandBuffer cmd, const Tensor& from, const DeviceImageView& to) {
  const vk::BufferView& t = from.buffer();
  // dvs's writes of the tensor, and every earlier use of the image (the application's, in any stage), come before
  // the copy; the image moves to the transfer layout (from UNDEFINED its contents are dropped).
  const VkBufferMemoryBarrier tensor_ready =
      buffer_barrier(t.buffer, t.offset, from.bytes(), kDvsWrites, VK_ACCESS_TRANSFER_READ_BIT);
  vkCmdPipelineBarrier(cmd, kDvsStages, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 1, &tensor_ready, 0, nullptr);
  const VkImageMemoryBarrier to_transfer =
      image_barrier(to.image, to.layout, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0,
                       nullptr, 1, &to_transfer);
  VkBufferImageCopy region{};
  region.bufferOffset = t.offset;
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {to.width, to.height, 1};
  vkCmdCopyBufferToImage(cmd, t.buffer, to.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
  // The image in the layout the application asked for, the copy's writes visible to whatever it does next; dvs's
  // later writes of the tensor wait for the copy's read (an execution dependency is enough for a read).
  const VkImageMemoryBarrier to_final =
      image_barrier(to.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, to.final_layout, VK_ACCESS_TRANSFER_WRITE_BIT,
                    VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT);
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, nullptr, 0,
                       nullptr, 1, &to_final);
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, kDvsStages, 0, 0, nullptr, 0, nullptr, 0, nullptr);
}

}  // namespace dvs::embed
