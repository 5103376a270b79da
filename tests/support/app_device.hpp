// A test playing an application that owns a Vulkan device and hands it to dvs (dvs::HostDevice): its own instance
// with the validation layer, synchronization validation included (also across submissions: the layer's
// QueueSubmit check, switched on through VK_LAYER_ENABLES before the instance is made), a messenger that records
// every message, a device and queue, and the buffers, images and command buffers an application records itself.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdlib>
#include <cstring>
#include <deque>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dvs/context.hpp"
#include "vk/device_info.hpp"

namespace dvs::test {

inline void app_check(VkResult r, const char* what) {
  if (r != VK_SUCCESS) throw std::runtime_error(std::string("test application: ") + what + " failed: " + std::to_string(r));
}

// What the application enables on its device.
struct AppFeatures {
  bool timeline_semaphore = true;
  bool float16 = false;
  bool memory_model_without_device_scope = false;
};

class AppDevice {
 public:
  struct Buffer {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    void* data = nullptr;  // mapped, coherent
    float* f32() const { return static_cast<float*>(data); }
  };
  struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkFormat format = VK_FORMAT_UNDEFINED;
    uint32_t width = 0, height = 0;
  };

  explicit AppDevice(AppFeatures features = {}) {
    // The layer reads its enables at vkCreateInstance; QueueSubmit synchronization validation has no
    // VkValidationFeatureEnableEXT of its own in this layer version (1.3.239), only this name. On Linux the list
    // is ':'-separated (',' is silently ignored: tried 2026-11-27). The value before is put back afterwards: under
    // tests/run_with_sync_validation.sh the same process's own contexts need it too.
    const char* enables_before = std::getenv("VK_LAYER_ENABLES");
    const std::string saved_enables = enables_before ? enables_before : "";
    setenv("VK_LAYER_ENABLES",
           "VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT:"
           "VALIDATION_CHECK_ENABLE_SYNCHRONIZATION_VALIDATION_QUEUE_SUBMIT",
           1);
    VkApplicationInfo ai{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    ai.pApplicationName = "dvs device-memory test";
    ai.apiVersion = VK_API_VERSION_1_2;
    const char* layer = "VK_LAYER_KHRONOS_validation";
    const char* ext = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
    VkValidationFeatureEnableEXT sync = VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
    VkValidationFeaturesEXT vf{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
    vf.enabledValidationFeatureCount = 1;
    vf.pEnabledValidationFeatures = &sync;
    VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ici.pNext = &vf;
    ici.pApplicationInfo = &ai;
    ici.enabledLayerCount = 1;
    ici.ppEnabledLayerNames = &layer;
    ici.enabledExtensionCount = 1;
    ici.ppEnabledExtensionNames = &ext;
    app_check(vkCreateInstance(&ici, nullptr, &instance), "vkCreateInstance with the validation layer");
    if (enables_before)
      setenv("VK_LAYER_ENABLES", saved_enables.c_str(), 1);
    else
      unsetenv("VK_LAYER_ENABLES");
    VkDebugUtilsMessengerCreateInfoEXT mci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    mci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    mci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT;
    mci.pfnUserCallback = record;
    mci.pUserData = &messages;
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    app_check(create(instance, &mci, nullptr, &messenger), "vkCreateDebugUtilsMessengerEXT");

    uint32_t n = 0;
    vkEnumeratePhysicalDevices(instance, &n, nullptr);
    std::vector<VkPhysicalDevice> pds(n);
    vkEnumeratePhysicalDevices(instance, &n, pds.data());
    std::vector<vk::DeviceCaps> caps;
    for (uint32_t i = 0; i < n; ++i) caps.push_back(vk::query_device_caps(pds[i], i));
    physical = pds[vk::select_device(caps, "")];
    uint32_t nq = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &nq, nullptr);
    std::vector<VkQueueFamilyProperties> families(nq);
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &nq, families.data());
    family = uint32_t(vk::pick_compute_queue_family(families));

    f12.timelineSemaphore = features.timeline_semaphore;
    f12.shaderFloat16 = features.float16;
    f12.vulkanMemoryModel = features.memory_model_without_device_scope;
    features2.pNext = &f12;
    float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qci.queueFamilyIndex = family;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.pNext = &features2;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    app_check(vkCreateDevice(physical, &dci, nullptr, &device), "vkCreateDevice");
    vkGetDeviceQueue(device, family, 0, &queue);
    VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pci.queueFamilyIndex = family;
    app_check(vkCreateCommandPool(device, &pci, nullptr, &pool), "vkCreateCommandPool");
  }

  ~AppDevice() {
    vkDeviceWaitIdle(device);
    for (auto& b : buffers) {
      vkDestroyBuffer(device, b.buffer, nullptr);
      vkFreeMemory(device, b.memory, nullptr);
    }
    for (auto& i : images) {
      vkDestroyImage(device, i.image, nullptr);
      vkFreeMemory(device, i.memory, nullptr);
    }
    for (VkSemaphore sem : semaphores) vkDestroySemaphore(device, sem, nullptr);
    vkDestroyCommandPool(device, pool, nullptr);
    vkDestroyDevice(device, nullptr);
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
    destroy(instance, messenger, nullptr);
    vkDestroyInstance(instance, nullptr);
  }
  AppDevice(const AppDevice&) = delete;
  AppDevice& operator=(const AppDevice&) = delete;

  // The device for dvs, with a queue lock that counts dvs's submissions and checks they come in pairs.
  HostDevice host() {
    HostDevice h;
    h.instance = instance;
    h.physical_device = physical;
    h.device = device;
    h.queue_family = family;
    h.queue = queue;
    h.instance_api_version = VK_API_VERSION_1_2;
    h.enabled_features = &features2;
    h.lock_queue = [this] {
      EXPECT_FALSE(queue_locked) << "dvs took the queue lock twice without unlocking";
      queue_locked = true;
      ++locks;
    };
    h.unlock_queue = [this] {
      EXPECT_TRUE(queue_locked) << "dvs unlocked the queue without locking it";
      queue_locked = false;
      ++unlocks;
    };
    return h;
  }

  VkSemaphore timeline_semaphore() {
    VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
    type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
    VkSemaphoreCreateInfo sci{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO, &type};
    VkSemaphore sem = VK_NULL_HANDLE;
    app_check(vkCreateSemaphore(device, &sci, nullptr, &sem), "vkCreateSemaphore");
    semaphores.push_back(sem);
    return sem;
  }

  // A host-visible, coherent, mapped buffer of `bytes` (zeroed) with both transfer usages.
  Buffer& buffer(VkDeviceSize bytes) {
    Buffer b;
    VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bci.size = bytes;
    bci.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    app_check(vkCreateBuffer(device, &bci, nullptr, &b.buffer), "vkCreateBuffer");
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device, b.buffer, &req);
    b.memory = allocate(req, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    app_check(vkBindBufferMemory(device, b.buffer, b.memory, 0), "vkBindBufferMemory");
    app_check(vkMapMemory(device, b.memory, 0, VK_WHOLE_SIZE, 0, &b.data), "vkMapMemory");
    std::memset(b.data, 0, size_t(bytes));
    buffers.push_back(b);
    return buffers.back();
  }

  // A device-local, optimally tiled 2-D image with the given usage.
  Image& image(VkFormat format, uint32_t width, uint32_t height, VkImageUsageFlags usage) {
    Image i;
    i.format = format, i.width = width, i.height = height;
    VkImageCreateInfo ci{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    ci.imageType = VK_IMAGE_TYPE_2D;
    ci.format = format;
    ci.extent = {width, height, 1};
    ci.mipLevels = 1;
    ci.arrayLayers = 1;
    ci.samples = VK_SAMPLE_COUNT_1_BIT;
    ci.tiling = VK_IMAGE_TILING_OPTIMAL;
    ci.usage = usage;
    ci.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    app_check(vkCreateImage(device, &ci, nullptr, &i.image), "vkCreateImage");
    VkMemoryRequirements req{};
    vkGetImageMemoryRequirements(device, i.image, &req);
    i.memory = allocate(req, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    app_check(vkBindImageMemory(device, i.image, i.memory, 0), "vkBindImageMemory");
    images.push_back(i);
    return images.back();
  }

  // One submission the application records itself (`record` fills the command buffer), waiting for each
  // (semaphore, value) pair at the transfer stage, then waited for with a fence (unless `host_wait` is false: then
  // the command buffer lives until the pool goes).
  void submit(const std::function<void(VkCommandBuffer)>& record,
              const std::vector<std::pair<VkSemaphore, uint64_t>>& waits = {}, bool host_wait = true) {
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    app_check(vkAllocateCommandBuffers(device, &ai, &cmd), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    app_check(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
    record(cmd);
    app_check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    std::vector<VkSemaphore> sems;
    std::vector<uint64_t> values;
    std::vector<VkPipelineStageFlags> stages;
    for (const auto& [s, v] : waits) sems.push_back(s), values.push_back(v), stages.push_back(VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkTimelineSemaphoreSubmitInfo tsi{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
    tsi.waitSemaphoreValueCount = uint32_t(values.size());
    tsi.pWaitSemaphoreValues = values.data();
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.pNext = &tsi;
    si.waitSemaphoreCount = uint32_t(sems.size());
    si.pWaitSemaphores = sems.data();
    si.pWaitDstStageMask = stages.data();
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd;
    if (!host_wait) {
      app_check(vkQueueSubmit(queue, 1, &si, VK_NULL_HANDLE), "vkQueueSubmit (application)");
      return;
    }
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence = VK_NULL_HANDLE;
    app_check(vkCreateFence(device, &fci, nullptr, &fence), "vkCreateFence");
    app_check(vkQueueSubmit(queue, 1, &si, fence), "vkQueueSubmit (application)");
    app_check(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
    vkDestroyFence(device, fence, nullptr);
    vkFreeCommandBuffers(device, pool, 1, &cmd);
  }

  // Records: `image` (in `layout`, written by transfers before) copied into `buffer` for the host to read; the
  // image is left in TRANSFER_SRC_OPTIMAL.
  static void record_image_readback(VkCommandBuffer cmd, const Image& image, VkImageLayout layout, VkBuffer buffer) {
    VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
    b.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    b.oldLayout = layout;
    b.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image.image;
    b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    if (layout != VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL)
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0,
                           nullptr, 1, &b);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {image.width, image.height, 1};
    vkCmdCopyImageToBuffer(cmd, image.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer, 1, &region);
    VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr,
                         0, nullptr);
  }

  // The application's own copy of `bytes` from `src` to `dst` for the host to read, after `wait` reaches `value`
  // (no wait when `wait` is null); waited for with a fence.
  void copy_buffer(VkBuffer src, VkBuffer dst, VkDeviceSize bytes, VkSemaphore wait = VK_NULL_HANDLE, uint64_t value = 0) {
    std::vector<std::pair<VkSemaphore, uint64_t>> waits;
    if (wait) waits.push_back({wait, value});
    submit(
        [&](VkCommandBuffer cmd) {
          VkBufferCopy region{0, 0, bytes};
          vkCmdCopyBuffer(cmd, src, dst, 1, &region);
          VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
          to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
          to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
          vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0,
                               nullptr, 0, nullptr);
        },
        waits);
  }

  std::string first_message() const { return messages.empty() ? "" : messages[0]; }

  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  uint32_t family = 0;
  VkQueue queue = VK_NULL_HANDLE;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 features2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  std::deque<Buffer> buffers;  // references to elements stay valid
  std::deque<Image> images;
  std::vector<VkSemaphore> semaphores;
  std::vector<std::string> messages;
  bool queue_locked = false;
  int locks = 0, unlocks = 0;

 private:
  static VKAPI_ATTR VkBool32 VKAPI_CALL record(VkDebugUtilsMessageSeverityFlagBitsEXT, VkDebugUtilsMessageTypeFlagsEXT,
                                               const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    static_cast<std::vector<std::string>*>(user)->push_back(data && data->pMessage ? data->pMessage : "");
    return VK_FALSE;
  }

  VkDeviceMemory allocate(const VkMemoryRequirements& req, VkMemoryPropertyFlags want) {
    VkPhysicalDeviceMemoryProperties mem{};
    vkGetPhysicalDeviceMemoryProperties(physical, &mem);
    uint32_t type = 0;
    while (type < mem.memoryTypeCount &&
           (!((req.memoryTypeBits >> type) & 1) || (mem.memoryTypes[type].propertyFlags & want) != want))
      ++type;
    if (type == mem.memoryTypeCount) throw std::runtime_error("test application: no memory type for a resource");
    VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    mai.allocationSize = req.size;
    mai.memoryTypeIndex = type;
    VkDeviceMemory m = VK_NULL_HANDLE;
    app_check(vkAllocateMemory(device, &mai, nullptr, &m), "vkAllocateMemory");
    return m;
  }
};

}  // namespace dvs::test
