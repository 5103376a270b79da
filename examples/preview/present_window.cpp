#include "present_window.hpp"

#include <algorithm>
#include <cstring>
#include <iostream>
#include <stdexcept>

namespace preview {

namespace {

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS)
    throw std::runtime_error(std::string("Vulkan: ") + what + " failed (VkResult " + std::to_string(int(r)) + ")");
}

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation(VkDebugUtilsMessageSeverityFlagBitsEXT, VkDebugUtilsMessageTypeFlagsEXT,
                                             const VkDebugUtilsMessengerCallbackDataEXT* data, void*) {
  std::cerr << "dvs-preview: validation: " << data->pMessage << "\n";
  return VK_FALSE;
}

uint32_t memory_type(VkPhysicalDevice physical, uint32_t bits, VkMemoryPropertyFlags want) {
  VkPhysicalDeviceMemoryProperties props;
  vkGetPhysicalDeviceMemoryProperties(physical, &props);
  for (uint32_t i = 0; i < props.memoryTypeCount; ++i)
    if ((bits & (1u << i)) && (props.memoryTypes[i].propertyFlags & want) == want) return i;
  throw std::runtime_error("Vulkan: no memory type with the properties asked for (a staging buffer or a panel image)");
}

}  // namespace

PresentWindow::PresentWindow(const WindowOptions& options) : options_(options) {
  if (!glfwInit()) throw std::runtime_error("GLFW could not start: is there a display? (DISPLAY unset: run under xvfb-run)");
  if (!glfwVulkanSupported()) throw std::runtime_error("GLFW found no Vulkan loader or no presentation support");
  glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
  glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
  const int width = options.panel_width * options.panels, height = options.panel_height;
  window_ = glfwCreateWindow(width, height, "dvs preview", nullptr, nullptr);
  if (!window_) throw std::runtime_error("GLFW could not open a " + std::to_string(width) + "x" + std::to_string(height) + " window");

  // The instance: what GLFW needs to present, plus debug utils for the validation layer.
  uint32_t glfw_count = 0;
  const char** glfw_extensions = glfwGetRequiredInstanceExtensions(&glfw_count);
  std::vector<const char*> extensions(glfw_extensions, glfw_extensions + glfw_count);
  std::vector<const char*> layers;
  if (options.validation) {
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    layers.push_back("VK_LAYER_KHRONOS_validation");
  }
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "dvs-preview";
  app.apiVersion = VK_API_VERSION_1_2;
  VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ici.pApplicationInfo = &app;
  ici.enabledExtensionCount = uint32_t(extensions.size());
  ici.ppEnabledExtensionNames = extensions.data();
  ici.enabledLayerCount = uint32_t(layers.size());
  ici.ppEnabledLayerNames = layers.data();
  check(vkCreateInstance(&ici, nullptr, &instance_), "vkCreateInstance");
  if (options.validation) {
    VkDebugUtilsMessengerCreateInfoEXT mci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    mci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    mci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT;
    mci.pfnUserCallback = on_validation;
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    if (create) check(create(instance_, &mci, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
  }
  check(glfwCreateWindowSurface(instance_, window_, nullptr, &surface_), "glfwCreateWindowSurface");

  // The GPU: the first (whose name contains options.device) with a queue family that computes, copies and presents.
  uint32_t count = 0;
  vkEnumeratePhysicalDevices(instance_, &count, nullptr);
  std::vector<VkPhysicalDevice> gpus(count);
  vkEnumeratePhysicalDevices(instance_, &count, gpus.data());
  std::string seen;
  for (VkPhysicalDevice gpu : gpus) {
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(gpu, &props);
    seen += std::string(seen.empty() ? "" : ", ") + props.deviceName;
    if (props.apiVersion < VK_API_VERSION_1_2) continue;
    if (!options.device.empty() && std::string(props.deviceName).find(options.device) == std::string::npos) continue;
    uint32_t families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(gpu, &families, nullptr);
    std::vector<VkQueueFamilyProperties> fams(families);
    vkGetPhysicalDeviceQueueFamilyProperties(gpu, &families, fams.data());
    for (uint32_t f = 0; f < families && !physical_; ++f) {
      VkBool32 presents = VK_FALSE;
      vkGetPhysicalDeviceSurfaceSupportKHR(gpu, f, surface_, &presents);
      if (presents && (fams[f].queueFlags & VK_QUEUE_COMPUTE_BIT)) {
        physical_ = gpu;
        family_ = f;
        device_name_ = props.deviceName;
      }
    }
    if (physical_) break;
  }
  if (!physical_)
    throw std::runtime_error("no Vulkan 1.2 GPU" + (options.device.empty() ? "" : " named '" + options.device + "'") +
                             " has a queue that computes and presents to this window (GPUs: " +
                             (seen.empty() ? "none" : seen) + ")");

  // The device: every core feature the GPU offers (dvs needs timelineSemaphore; the rest enables its optional
  // paths) and the swapchain extension.
  features11_.pNext = &features12_;
  features_.pNext = &features11_;
  vkGetPhysicalDeviceFeatures2(physical_, &features_);
  if (!features12_.timelineSemaphore)
    throw std::runtime_error(device_name_ + " lacks timelineSemaphore, which dvs needs (" +
                             std::to_string(dvs::Context::required_features().size()) + " required features)");
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qci.queueFamilyIndex = family_;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  const char* device_extensions[] = {VK_KHR_SWAPCHAIN_EXTENSION_NAME};
  VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dci.pNext = &features_;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  dci.enabledExtensionCount = 1;
  dci.ppEnabledExtensionNames = device_extensions;
  check(vkCreateDevice(physical_, &dci, nullptr, &device_), "vkCreateDevice");
  vkGetDeviceQueue(device_, family_, 0, &queue_);

  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = family_;
  check(vkCreateCommandPool(device_, &pci, nullptr, &pool_), "vkCreateCommandPool");
  VkCommandBufferAllocateInfo cai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  cai.commandPool = pool_;
  cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cai.commandBufferCount = 1;
  check(vkAllocateCommandBuffers(device_, &cai, &commands_), "vkAllocateCommandBuffers");
  VkSemaphoreCreateInfo sci{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  check(vkCreateSemaphore(device_, &sci, nullptr, &acquired_), "vkCreateSemaphore");
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  fci.flags = VK_FENCE_CREATE_SIGNALED_BIT;
  check(vkCreateFence(device_, &fci, nullptr, &done_), "vkCreateFence");

  pixels_.assign(size_t(width) * size_t(height) * 4, 0);
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = pixels_.size();
  bci.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  check(vkCreateBuffer(device_, &bci, nullptr, &staging_), "vkCreateBuffer (staging)");
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(device_, staging_, &req);
  VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = memory_type(physical_, req.memoryTypeBits,
                                    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  check(vkAllocateMemory(device_, &mai, nullptr, &staging_memory_), "vkAllocateMemory (staging)");
  check(vkBindBufferMemory(device_, staging_, staging_memory_, 0), "vkBindBufferMemory");
  check(vkMapMemory(device_, staging_memory_, 0, VK_WHOLE_SIZE, 0, reinterpret_cast<void**>(&mapped_)), "vkMapMemory");
  create_swapchain();
}

void PresentWindow::create_swapchain() {
  VkSurfaceCapabilitiesKHR caps;
  check(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(physical_, surface_, &caps), "vkGetPhysicalDeviceSurfaceCapabilitiesKHR");
  if (!(caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_DST_BIT))
    throw std::runtime_error("the window's swapchain images cannot be copied into (no TRANSFER_DST usage) on " + device_name_);
  uint32_t n = 0;
  vkGetPhysicalDeviceSurfaceFormatsKHR(physical_, surface_, &n, nullptr);
  std::vector<VkSurfaceFormatKHR> formats(n);
  vkGetPhysicalDeviceSurfaceFormatsKHR(physical_, surface_, &n, formats.data());
  format_ = VK_FORMAT_UNDEFINED;
  for (VkFormat want : {VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_R8G8B8A8_SRGB, VK_FORMAT_B8G8R8A8_SRGB})
    for (const auto& f : formats)
      if (format_ == VK_FORMAT_UNDEFINED && f.format == want) format_ = want;
  if (format_ == VK_FORMAT_UNDEFINED) throw std::runtime_error("the window offers no 8-bit RGBA or BGRA swapchain format");
  bgra_ = format_ == VK_FORMAT_B8G8R8A8_UNORM || format_ == VK_FORMAT_B8G8R8A8_SRGB;
  vkGetPhysicalDeviceSurfacePresentModesKHR(physical_, surface_, &n, nullptr);
  std::vector<VkPresentModeKHR> modes(n);
  vkGetPhysicalDeviceSurfacePresentModesKHR(physical_, surface_, &n, modes.data());
  VkPresentModeKHR mode = VK_PRESENT_MODE_FIFO_KHR;
  if (!options_.vsync)
    for (VkPresentModeKHR want : {VK_PRESENT_MODE_MAILBOX_KHR, VK_PRESENT_MODE_IMMEDIATE_KHR})
      if (mode == VK_PRESENT_MODE_FIFO_KHR && std::find(modes.begin(), modes.end(), want) != modes.end()) mode = want;
  extent_ = caps.currentExtent;
  if (extent_.width == UINT32_MAX)
    extent_ = {uint32_t(options_.panel_width * options_.panels), uint32_t(options_.panel_height)};
  VkSwapchainCreateInfoKHR sci{VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR};
  sci.surface = surface_;
  sci.minImageCount = std::max(caps.minImageCount, 2u);
  if (caps.maxImageCount) sci.minImageCount = std::min(sci.minImageCount, caps.maxImageCount);
  sci.imageFormat = format_;
  sci.imageColorSpace = VK_COLOR_SPACE_SRGB_NONLINEAR_KHR;
  sci.imageExtent = extent_;
  sci.imageArrayLayers = 1;
  sci.imageUsage = VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  sci.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  sci.preTransform = caps.currentTransform;
  sci.compositeAlpha = (caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR)
                           ? VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR
                           : VkCompositeAlphaFlagBitsKHR(caps.supportedCompositeAlpha & -caps.supportedCompositeAlpha);
  sci.presentMode = mode;
  sci.clipped = VK_TRUE;
  check(vkCreateSwapchainKHR(device_, &sci, nullptr, &swapchain_), "vkCreateSwapchainKHR");
  vkGetSwapchainImagesKHR(device_, swapchain_, &n, nullptr);
  images_.resize(n);
  vkGetSwapchainImagesKHR(device_, swapchain_, &n, images_.data());
  VkSemaphoreCreateInfo semaphore{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  copied_.assign(n, VK_NULL_HANDLE);
  for (VkSemaphore& s : copied_) check(vkCreateSemaphore(device_, &semaphore, nullptr, &s), "vkCreateSemaphore");
}

void PresentWindow::destroy_swapchain() {
  if (swapchain_) vkDestroySwapchainKHR(device_, swapchain_, nullptr);
  swapchain_ = VK_NULL_HANDLE;
  images_.clear();
  for (VkSemaphore s : copied_) vkDestroySemaphore(device_, s, nullptr);
  copied_.clear();
}

PresentWindow::~PresentWindow() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    destroy_swapchain();
    for (DevicePanel& p : device_panels_) {
      vkDestroyImage(device_, p.image, nullptr);
      vkFreeMemory(device_, p.memory, nullptr);
    }
    if (mapped_) vkUnmapMemory(device_, staging_memory_);
    vkDestroyBuffer(device_, staging_, nullptr);
    vkFreeMemory(device_, staging_memory_, nullptr);
    vkDestroyFence(device_, done_, nullptr);
    vkDestroySemaphore(device_, acquired_, nullptr);
    vkDestroyCommandPool(device_, pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (surface_) vkDestroySurfaceKHR(instance_, surface_, nullptr);
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
  if (window_) glfwDestroyWindow(window_);
  glfwTerminate();
}

VkImage PresentWindow::device_panel(int i, VkFormat format) {
  device_panels_.resize(size_t(options_.panels));
  DevicePanel& p = device_panels_.at(size_t(i));
  if (p.image) return p.image;
  VkImageCreateInfo ci{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ci.imageType = VK_IMAGE_TYPE_2D;
  ci.format = format;
  ci.extent = {uint32_t(options_.panel_width), uint32_t(options_.panel_height), 1};
  ci.mipLevels = 1;
  ci.arrayLayers = 1;
  ci.samples = VK_SAMPLE_COUNT_1_BIT;
  ci.tiling = VK_IMAGE_TILING_OPTIMAL;
  ci.usage = VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  check(vkCreateImage(device_, &ci, nullptr, &p.image), "vkCreateImage (a panel image)");
  VkMemoryRequirements req{};
  vkGetImageMemoryRequirements(device_, p.image, &req);
  VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = memory_type(physical_, req.memoryTypeBits, 0);
  check(vkAllocateMemory(device_, &mai, nullptr, &p.memory), "vkAllocateMemory (a panel image)");
  check(vkBindImageMemory(device_, p.image, p.memory, 0), "vkBindImageMemory (a panel image)");
  return p.image;
}

void PresentWindow::wait_before_present(VkSemaphore semaphore, uint64_t value) {
  present_wait_ = semaphore;
  present_wait_value_ = value;
}

dvs::HostDevice PresentWindow::host_device() const {
  dvs::HostDevice h;
  h.instance = instance_;
  h.physical_device = physical_;
  h.device = device_;
  h.queue_family = family_;
  h.queue = queue_;
  h.instance_api_version = VK_API_VERSION_1_2;
  h.enabled_features = &features_;
  h.enabled_extensions = {VK_KHR_SWAPCHAIN_EXTENSION_NAME};
  return h;  // one thread submits (this one): no queue lock needed
}

uint8_t* PresentWindow::panel(int i) {
  return pixels_.data() + size_t(i) * size_t(options_.panel_width) * size_t(options_.panel_height) * 4;
}

std::vector<uint8_t> PresentWindow::window_pixels() const {
  const size_t W = size_t(options_.panel_width), H = size_t(options_.panel_height), P = size_t(options_.panels);
  std::vector<uint8_t> out(W * H * P * 4);
  for (size_t p = 0; p < P; ++p)
    for (size_t y = 0; y < H; ++y)
      std::memcpy(&out[(y * W * P + p * W) * 4], &pixels_[(p * H * W + y * W) * 4], W * 4);
  return out;
}

void PresentWindow::present() {
  check(vkWaitForFences(device_, 1, &done_, VK_TRUE, UINT64_MAX), "vkWaitForFences");
  uint32_t index = 0;
  VkResult r = vkAcquireNextImageKHR(device_, swapchain_, UINT64_MAX, acquired_, VK_NULL_HANDLE, &index);
  if (r == VK_ERROR_OUT_OF_DATE_KHR) {  // the window changed under us: make the swapchain again, skip this frame
    vkDeviceWaitIdle(device_);
    destroy_swapchain();
    create_swapchain();
    return;
  }
  if (r != VK_SUBOPTIMAL_KHR) check(r, "vkAcquireNextImageKHR");
  check(vkResetFences(device_, 1, &done_), "vkResetFences");
  if (bgra_) {
    for (size_t i = 0; i < pixels_.size(); i += 4) {
      mapped_[i] = pixels_[i + 2];
      mapped_[i + 1] = pixels_[i + 1];
      mapped_[i + 2] = pixels_[i];
      mapped_[i + 3] = pixels_[i + 3];
    }
  } else {
    std::memcpy(mapped_, pixels_.data(), pixels_.size());
  }

  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(commands_, &begin), "vkBeginCommandBuffer");
  VkImageMemoryBarrier to_copy{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  to_copy.srcAccessMask = 0;
  to_copy.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_copy.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  to_copy.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  to_copy.srcQueueFamilyIndex = to_copy.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  to_copy.image = images_[index];
  to_copy.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  vkCmdPipelineBarrier(commands_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0,
                       nullptr, 1, &to_copy);
  std::vector<VkBufferImageCopy> regions;
  const uint32_t W = uint32_t(options_.panel_width), H = uint32_t(options_.panel_height);
  std::vector<VkImageBlit> blits(options_.panels);
  for (uint32_t p = 0; p < uint32_t(options_.panels); ++p) {
    if (p * W >= extent_.width) break;  // a window smaller than asked for shows what fits
    if (p < device_panels_.size() && device_panels_[p].image) {  // blitted below
      const int32_t w = int32_t(std::min(W, extent_.width - p * W)), h = int32_t(std::min(H, extent_.height));
      VkImageBlit& b = blits[p];
      b.srcSubresource = b.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
      b.srcOffsets[1] = {w, h, 1};
      b.dstOffsets[0] = {int32_t(p * W), 0, 0};
      b.dstOffsets[1] = {int32_t(p * W) + w, h, 1};
      vkCmdBlitImage(commands_, device_panels_[p].image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, images_[index],
                     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &b, VK_FILTER_NEAREST);
      continue;
    }
    VkBufferImageCopy c{};
    c.bufferOffset = VkDeviceSize(p) * W * H * 4;
    c.bufferRowLength = W;
    c.bufferImageHeight = H;
    c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    c.imageOffset = {int32_t(p * W), 0, 0};
    c.imageExtent = {std::min(W, extent_.width - p * W), std::min(H, extent_.height), 1};
    regions.push_back(c);
  }
  if (!regions.empty())
    vkCmdCopyBufferToImage(commands_, staging_, images_[index], VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           uint32_t(regions.size()), regions.data());
  VkImageMemoryBarrier to_present = to_copy;
  to_present.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_present.dstAccessMask = 0;
  to_present.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  to_present.newLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
  vkCmdPipelineBarrier(commands_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 0,
                       nullptr, 1, &to_present);
  check(vkEndCommandBuffer(commands_), "vkEndCommandBuffer");

  // The acquired image, and (for device panels) the renderer's ticket on its timeline.
  const VkSemaphore waits[2] = {acquired_, present_wait_};
  const uint64_t wait_values[2] = {0, present_wait_value_};
  const VkPipelineStageFlags wait_stages[2] = {VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT};
  VkTimelineSemaphoreSubmitInfo timeline{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
  timeline.waitSemaphoreValueCount = present_wait_ ? 2 : 1;
  timeline.pWaitSemaphoreValues = wait_values;
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.pNext = &timeline;
  submit.waitSemaphoreCount = present_wait_ ? 2 : 1;
  submit.pWaitSemaphores = waits;
  submit.pWaitDstStageMask = wait_stages;
  present_wait_ = VK_NULL_HANDLE;
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &commands_;
  submit.signalSemaphoreCount = 1;
  submit.pSignalSemaphores = &copied_[index];
  check(vkQueueSubmit(queue_, 1, &submit, done_), "vkQueueSubmit");
  VkPresentInfoKHR pi{VK_STRUCTURE_TYPE_PRESENT_INFO_KHR};
  pi.waitSemaphoreCount = 1;
  pi.pWaitSemaphores = &copied_[index];
  pi.swapchainCount = 1;
  pi.pSwapchains = &swapchain_;
  pi.pImageIndices = &index;
  r = vkQueuePresentKHR(queue_, &pi);
  if (r == VK_ERROR_OUT_OF_DATE_KHR || r == VK_SUBOPTIMAL_KHR) {
    vkDeviceWaitIdle(device_);
    destroy_swapchain();
    create_swapchain();
  } else {
    check(r, "vkQueuePresentKHR");
  }
}

}  // namespace preview
