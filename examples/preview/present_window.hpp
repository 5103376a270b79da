// The application's side of the embedding: a GLFW window with the example's OWN Vulkan instance, device, queue
// and swapchain. The device is created with what dvs::Context::required_features() asks for (Vulkan 1.2,
// timelineSemaphore) and every other core feature the GPU has, so dvs can use its optional paths; host_device()
// hands the objects to dvs::Context. Each frame the caller fills panels of a host-visible RGBA8 buffer, and
// present() copies them side by side into the swapchain image (vkCmdCopyBufferToImage: no graphics pipeline);
// a panel may instead come from a device image dvs rendered into (device_panel, blitted: --device-image).
#pragma once
#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <cstdint>
#include <string>
#include <vector>

#include "dvs/context.hpp"

namespace preview {

struct WindowOptions {
  int panel_width = 720, panel_height = 480, panels = 3;
  std::string device;     // substring of the GPU's name; "" = the first that can present
  bool validation = false;  // the Khronos validation layer on the example's instance
  bool vsync = true;        // FIFO present; false = IMMEDIATE or MAILBOX where offered (frame times unthrottled)
};

class PresentWindow {
 public:
  explicit PresentWindow(const WindowOptions& options);  // throws std::runtime_error naming what failed
  ~PresentWindow();
  PresentWindow(const PresentWindow&) = delete;
  PresentWindow& operator=(const PresentWindow&) = delete;

  GLFWwindow* window() const { return window_; }
  dvs::HostDevice host_device() const;
  std::string device_name() const { return device_name_; }

  // Panel i's pixels, RGBA8 row-major [H,W,4], in host memory; write them, then present().
  uint8_t* panel(int i);
  // Or panel i shown from an image on the device (made on the first call, panel-sized, TRANSFER_DST and
  // TRANSFER_SRC usage) that dvs renders into: present() blits it (converting the format)
  // from TRANSFER_SRC_OPTIMAL, the layout the renderer must leave it in, without a host round trip.
  VkImage device_panel(int i, VkFormat format);
  // The next present()'s copies wait (on the device) until `semaphore` (a timeline) reaches `value`: dvs's ticket.
  void wait_before_present(VkSemaphore semaphore, uint64_t value);
  // Copies every panel into the next swapchain image and presents it; waits for the previous frame first.
  void present();
  // The whole window as last presented (RGBA8 [H, panels·W, 4]), for a PNG screenshot.
  std::vector<uint8_t> window_pixels() const;

 private:
  void create_swapchain();
  void destroy_swapchain();

  WindowOptions options_;
  GLFWwindow* window_ = nullptr;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkSurfaceKHR surface_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  uint32_t family_ = 0;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::string device_name_;
  // The feature chain the device was created with: HostDevice::enabled_features points at it (dvs reads it while
  // its Context is made, to know which optional features it may use).
  VkPhysicalDeviceFeatures2 features_{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  VkPhysicalDeviceVulkan11Features features11_{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES};
  VkPhysicalDeviceVulkan12Features features12_{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkSwapchainKHR swapchain_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  std::vector<VkImage> images_;
  VkBuffer staging_ = VK_NULL_HANDLE;
  VkDeviceMemory staging_memory_ = VK_NULL_HANDLE;
  uint8_t* mapped_ = nullptr;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkCommandBuffer commands_ = VK_NULL_HANDLE;
  VkSemaphore acquired_ = VK_NULL_HANDLE;
  std::vector<VkSemaphore> copied_;  // one per swapchain image: a present may still hold the previous one
  VkFence done_ = VK_NULL_HANDLE;
  VkExtent2D extent_{};
  bool bgra_ = false;            // the swapchain stores B,G,R,A: panels are swizzled into the staging buffer
  std::vector<uint8_t> pixels_;  // the panels, one after the other, each [H,W,4] RGBA
  struct DevicePanel {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
  };
  std::vector<DevicePanel> device_panels_;  // per panel; no image: the panel comes from host memory
  VkSemaphore present_wait_ = VK_NULL_HANDLE;
  uint64_t present_wait_value_ = 0;
};

}  // namespace preview
