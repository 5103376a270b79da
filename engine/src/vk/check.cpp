#include "vk/check.hpp"

#include <cstring>

namespace dvs::vk {

const char* const kOutOfMemoryHint =
    ". Try --vae-tiling, a smaller --height/--width, fewer --frames, or a device with more memory (dvs plan "
    "shows what each stage needs)";

const char* result_name(VkResult r) {
  switch (r) {
    case VK_SUCCESS: return "VK_SUCCESS";
    case VK_NOT_READY: return "VK_NOT_READY";
    case VK_TIMEOUT: return "VK_TIMEOUT";
    case VK_INCOMPLETE: return "VK_INCOMPLETE";
    case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED: return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT: return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT: return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_TOO_MANY_OBJECTS: return "VK_ERROR_TOO_MANY_OBJECTS";
    case VK_ERROR_FORMAT_NOT_SUPPORTED: return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    case VK_ERROR_FRAGMENTED_POOL: return "VK_ERROR_FRAGMENTED_POOL";
    case VK_ERROR_OUT_OF_POOL_MEMORY: return "VK_ERROR_OUT_OF_POOL_MEMORY";
    default: return "VkResult(unknown)";
  }
}

void throw_vk_error(VkResult r, const char* call, const char* file, int line) {
  const std::string msg = std::string("Vulkan call failed with ") + result_name(r) + " (" + std::to_string(int(r)) +
                          "): " + call + " at " + file + ":" + std::to_string(line);
  const std::string function(call, std::strcspn(call, "("));  // "vkQueueSubmit" of "vkQueueSubmit(queue_, ...)"
  if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY)
    throw DeviceOutOfMemory("the device ran out of memory (" + std::string(result_name(r)) + " from " + function + ")",
                            kOutOfMemoryHint);
  if (r == VK_ERROR_DEVICE_LOST)
    throw DeviceLost("the GPU device was lost (VK_ERROR_DEVICE_LOST from " + function + "): the driver reset it "
                     "after a shader fault, a timeout or a hardware error, and nothing on it survives. What to try: run the same command again "
                     "(stages already finished are taken from the cache); if it happens again, look for the GPU's "
                     "error in the kernel log (dmesg), update the driver, or give the GPU less work per submission "
                     "(--vae-tiling, fewer --frames, a smaller --height/--width)");
  throw Error(msg);
}

}  // namespace dvs::vk
