#include "vk/context.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "vk/check.hpp"
#include "vk/host_device.hpp"
#include "vk/memory.hpp"
#include "vk/pipeline.hpp"
#include "vk/profiler.hpp"
#include "vk/transfer.hpp"
#include "vk/validation_log.hpp"

namespace dvs::vk {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

bool env_on(const char* name) {
  const char* v = std::getenv(name);
  return v && *v && std::strcmp(v, "0") != 0;
}

bool instance_has_layer(const char* name) {
  uint32_t n = 0;
  vkEnumerateInstanceLayerProperties(&n, nullptr);
  std::vector<VkLayerProperties> layers(n);
  vkEnumerateInstanceLayerProperties(&n, layers.data());
  for (auto& l : layers)
    if (std::strcmp(l.layerName, name) == 0) return true;
  return false;
}

bool instance_has_extension(const char* name) {
  uint32_t n = 0;
  vkEnumerateInstanceExtensionProperties(nullptr, &n, nullptr);
  std::vector<VkExtensionProperties> exts(n);
  vkEnumerateInstanceExtensionProperties(nullptr, &n, exts.data());
  for (auto& e : exts)
    if (std::strcmp(e.extensionName, name) == 0) return true;
  return false;
}

VKAPI_ATTR VkBool32 VKAPI_CALL on_debug_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                VkDebugUtilsMessageTypeFlagsEXT,
                                                const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  std::string msg = std::string(severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "[validation error] "
                                                                                           : "[validation warning] ") +
                    (data && data->pMessage ? data->pMessage : "");
  std::cerr << msg << "\n";
  static_cast<Context*>(user)->add_validation_message(std::move(msg));
  return VK_FALSE;
}

// Creates an instance; validation adds the Khronos layer and a debug messenger.
VkInstance create_instance(bool validation, bool& portability) {
  uint32_t loader_version = VK_API_VERSION_1_0;
  vkEnumerateInstanceVersion(&loader_version);
  if (loader_version < VK_API_VERSION_1_2)
    throw Error("The Vulkan loader supports only " + version_string(loader_version) +
                "; dvs needs Vulkan 1.2. Update the Vulkan loader (libvulkan1).");
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "dvs";
  app.pEngineName = "dvs";
  app.apiVersion = loader_version >= VK_API_VERSION_1_3 ? VK_API_VERSION_1_3 : VK_API_VERSION_1_2;

  std::vector<const char*> layers, exts;
  if (validation) {
    if (!instance_has_layer(kValidationLayer))
      throw Error("Validation was requested but VK_LAYER_KHRONOS_validation is not installed "
                  "(apt-get install vulkan-validationlayers).");
    layers.push_back(kValidationLayer);
    exts.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  portability = instance_has_extension(VK_KHR_PORTABILITY_ENUMERATION_EXTENSION_NAME);
  if (portability) exts.push_back(VK_KHR_PORTABILITY_ENUMERATION_EXTENSION_NAME);

  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  ci.enabledLayerCount = uint32_t(layers.size());
  ci.ppEnabledLayerNames = layers.data();
  ci.enabledExtensionCount = uint32_t(exts.size());
  ci.ppEnabledExtensionNames = exts.data();
  if (portability) ci.flags |= VK_INSTANCE_CREATE_ENUMERATE_PORTABILITY_BIT_KHR;
  VkInstance instance = VK_NULL_HANDLE;
  VkResult r = vkCreateInstance(&ci, nullptr, &instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER)
    throw Error("No Vulkan driver is installed (vkCreateInstance: VK_ERROR_INCOMPATIBLE_DRIVER). For a CPU-only "
                "machine: apt-get install mesa-vulkan-drivers.");
  VK_CHECK(r);
  return instance;
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
  uint32_t n = 0;
  VK_CHECK(vkEnumeratePhysicalDevices(instance, &n, nullptr));
  std::vector<VkPhysicalDevice> pds(n);
  VK_CHECK(vkEnumeratePhysicalDevices(instance, &n, pds.data()));
  return pds;
}

}  // namespace

std::vector<DeviceCaps> list_devices() {
  bool portability = false;
  VkInstance instance = create_instance(false, portability);
  std::vector<DeviceCaps> out;
  try {
    auto pds = physical_devices(instance);
    for (uint32_t i = 0; i < pds.size(); ++i) out.push_back(query_device_caps(pds[i], i, instance));
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
  vkDestroyInstance(instance, nullptr);
  return out;
}

Context::Context(const ContextOptions& options) {
  validation_ = options.validation || env_on("DVS_VALIDATION");
  bool portability = false;
  instance_ = create_instance(validation_, portability);
  try {
    if (validation_) {
      auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
      VkDebugUtilsMessengerCreateInfoEXT mci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
      mci.messageSeverity =
          VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
      mci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT;
      mci.pfnUserCallback = on_debug_message;
      mci.pUserData = this;
      if (create) VK_CHECK(create(instance_, &mci, nullptr, &messenger_));
      set_object_name_ = reinterpret_cast<PFN_vkSetDebugUtilsObjectNameEXT>(
          vkGetInstanceProcAddr(instance_, "vkSetDebugUtilsObjectNameEXT"));
    }

    auto pds = physical_devices(instance_);
    std::vector<DeviceCaps> all;
    for (uint32_t i = 0; i < pds.size(); ++i) all.push_back(query_device_caps(pds[i], i, instance_));
    uint32_t chosen = select_device(all, options.device);
    physical_ = pds[chosen];
    caps_ = all[chosen];
    if (caps_.api_version < VK_API_VERSION_1_2)
      throw Error("Device '" + caps_.name + "' supports Vulkan " + version_string(caps_.api_version) +
                  "; dvs needs 1.2. Choose another device with --device or update its driver.");

    // The queue family query_device_caps picked (a compute-only one where the device has one).
    if (!caps_.has_compute_queue) throw Error("Device '" + caps_.name + "' has no compute queue.");
    queue_family_ = caps_.queue_family;

    // Enable every optional feature the device has and dvs may use.
    VkPhysicalDeviceVulkan11Features f11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES};
    VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceSubgroupSizeControlFeatures fsg{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_SIZE_CONTROL_FEATURES};
    VkPhysicalDeviceShaderAtomicFloatFeaturesEXT fat{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_ATOMIC_FLOAT_FEATURES_EXT};
    VkPhysicalDeviceFeatures2 feats{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    feats.pNext = &f11;
    f11.pNext = &f12;
    f11.storageBuffer16BitAccess = caps_.storage_16bit;
    f11.uniformAndStorageBuffer16BitAccess = caps_.storage_16bit;
    f12.storageBuffer8BitAccess = caps_.storage_8bit;
    f12.uniformAndStorageBuffer8BitAccess = caps_.storage_8bit;
    f12.shaderFloat16 = caps_.float16_arithmetic;
    f12.shaderInt8 = caps_.int8_arithmetic;
    f12.timelineSemaphore = VK_TRUE;  // core in Vulkan 1.2: every submission signals the context's timeline
    void** tail = &f12.pNext;
    std::vector<const char*> exts;
    if (caps_.subgroup_size_control) {
      fsg.subgroupSizeControl = VK_TRUE;
      fsg.computeFullSubgroups = VK_TRUE;
      *tail = &fsg;
      tail = &fsg.pNext;
      if (caps_.api_version < VK_API_VERSION_1_3) exts.push_back("VK_EXT_subgroup_size_control");
    }
    if (caps_.float32_atomic_add) {
      fat.shaderBufferFloat32AtomicAdd = VK_TRUE;
      *tail = &fat;
      tail = &fat.pNext;
      exts.push_back("VK_EXT_shader_atomic_float");
    }
    // Tensor cores: the coopmat shaders are SPIR-V 1.6 with the Vulkan memory model. Enabled only for them:
    // with the model on, the other shaders' Device-scope atomics (cast, nonfinite) also need
    // vulkanMemoryModelDeviceScope (VUID-RuntimeSpirv-vulkanMemoryModel-06265; lavapipe fails validation).
    VkPhysicalDeviceCooperativeMatrixFeaturesKHR fcm{};
    fcm.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_FEATURES_KHR;
    if (caps_.cooperative_matrix) {
      VkPhysicalDeviceVulkan12Features has12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
      VkPhysicalDeviceFeatures2 has{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &has12};
      vkGetPhysicalDeviceFeatures2(physical_, &has);
      f12.vulkanMemoryModel = VK_TRUE;
      f12.vulkanMemoryModelDeviceScope = has12.vulkanMemoryModelDeviceScope;
    }
    if (caps_.cooperative_matrix) {
      fcm.cooperativeMatrix = VK_TRUE;
      *tail = &fcm;
      tail = &fcm.pNext;
      exts.push_back(VK_KHR_COOPERATIVE_MATRIX_EXTENSION_NAME);
    }
    // The coopmat2 features the attention kernel's softmax uses and those the coopmat2 GEMM uses (and only those).
    VkPhysicalDeviceCooperativeMatrix2FeaturesNV fcm2{};
    fcm2.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_2_FEATURES_NV;
    if (caps_.cooperative_matrix2_row_ops || caps_.cooperative_matrix2_gemm) {
      fcm2.cooperativeMatrixReductions = caps_.cooperative_matrix2_row_ops ? VK_TRUE : VK_FALSE;
      fcm2.cooperativeMatrixConversions = caps_.cooperative_matrix2_row_ops ? VK_TRUE : VK_FALSE;
      fcm2.cooperativeMatrixPerElementOperations = VK_TRUE;
      if (caps_.cooperative_matrix2_gemm) {
        fcm2.cooperativeMatrixWorkgroupScope = VK_TRUE;
        fcm2.cooperativeMatrixFlexibleDimensions = VK_TRUE;
        fcm2.cooperativeMatrixTensorAddressing = VK_TRUE;
      }
      *tail = &fcm2;
      tail = &fcm2.pNext;
      exts.push_back(VK_NV_COOPERATIVE_MATRIX_2_EXTENSION_NAME);
    }
    // glslang compiles local_size_x_id for Vulkan 1.3 as LocalSizeId, which needs maintenance4 (every 1.3
    // device has it; cooperative_matrix implies 1.3).
    VkPhysicalDeviceMaintenance4Features fm4{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_4_FEATURES};
    if (caps_.cooperative_matrix) {
      fm4.maintenance4 = VK_TRUE;
      *tail = &fm4;
      tail = &fm4.pNext;
    }
    // Compiled-code statistics (registers, spills) for the pipelines that ask for them (PipelineCache).
    VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR fpe{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
    if (caps_.pipeline_executable_info) {
      fpe.pipelineExecutableInfo = VK_TRUE;
      *tail = &fpe;
      tail = &fpe.pNext;
      exts.push_back(VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME);
    }
    if (caps_.has_extension("VK_KHR_portability_subset")) exts.push_back("VK_KHR_portability_subset");
    if (caps_.memory_budget_ext) exts.push_back(VK_EXT_MEMORY_BUDGET_EXTENSION_NAME);  // the Allocator reads heap budgets
    VkPhysicalDeviceFeatures2 supported{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    vkGetPhysicalDeviceFeatures(physical_, &supported.features);
    feats.features.shaderInt64 = supported.features.shaderInt64;
    feats.features.shaderInt16 = supported.features.shaderInt16;
    feats.features.shaderFloat64 = supported.features.shaderFloat64;

    float priority = 1.0f;
    VkDeviceQueueCreateInfo qci[2]{{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO}, {VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO}};
    qci[0].queueFamilyIndex = queue_family_;
    qci[0].queueCount = 1;
    qci[0].pQueuePriorities = &priority;
    // A transfer-only family (a copy engine) for streamed weights, where the device has one.
    transfer_family_ = caps_.transfer_queue_family >= 0 ? uint32_t(caps_.transfer_queue_family) : queue_family_;
    qci[1].queueFamilyIndex = transfer_family_;
    qci[1].queueCount = 1;
    qci[1].pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.pNext = &feats;
    dci.queueCreateInfoCount = transfer_family_ != queue_family_ ? 2 : 1;
    dci.pQueueCreateInfos = qci;
    dci.enabledExtensionCount = uint32_t(exts.size());
    dci.ppEnabledExtensionNames = exts.data();
    VK_CHECK(vkCreateDevice(physical_, &dci, nullptr, &device_));
    vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
    transfer_queue_ = queue_;
    if (transfer_family_ != queue_family_) vkGetDeviceQueue(device_, transfer_family_, 0, &transfer_queue_);
    create_services(options);
  } catch (...) {
    release();
    throw;
  }
}

Context::Context(const HostDevice& host, const ContextOptions& options) {
  if (bool(host.lock_queue) != bool(host.unlock_queue))
    throw Error("HostDevice: lock_queue and unlock_queue must both be set or both be empty (dvs calls them in pairs "
                "around every vkQueueSubmit on the application's queue).",
                ErrorKind::invalid_argument);
  caps_ = host_device_caps(host);
  owns_device_ = false;
  instance_ = host.instance;
  physical_ = host.physical_device;
  device_ = host.device;
  queue_ = host.queue;
  queue_family_ = host.queue_family;
  transfer_queue_ = host.queue;  // the application's one queue: uploads go there too
  transfer_family_ = host.queue_family;
  lock_queue_ = host.lock_queue;
  unlock_queue_ = host.unlock_queue;
  try {
    create_services(options);
  } catch (...) {
    release();
    throw;
  }
}

void Context::create_services(const ContextOptions& options) {
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = queue_family_;
  VK_CHECK(vkCreateCommandPool(device_, &pci, nullptr, &command_pool_));
  VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
  type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
  type.initialValue = 0;
  VkSemaphoreCreateInfo sci{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  sci.pNext = &type;
  VK_CHECK(vkCreateSemaphore(device_, &sci, nullptr, &timeline_));

  allocator_ = std::make_unique<Allocator>(*this);
  transfer_ = std::make_unique<Transfer>(*this);
  pipelines_ = std::make_unique<PipelineCache>(*this, options.pipeline_cache_file, options.cache_dir);
  profiler_ = std::make_unique<Profiler>(env_on("DVS_PROFILE"));
}

void Context::override_limits(const LimitOverrides& extra) {
  caps_.max_storage_buffer_range = caps_.device_limits.binding;
  caps_.max_texel_buffer_elements = caps_.device_limits.texels;
  caps_.max_memory_allocation_size = caps_.device_limits.alloc;
  for (int i = 0; i < 3; ++i) caps_.max_workgroup_count[i] = caps_.device_limits.groups[i];
  caps_.memory_budget.bytes = caps_.device_limits.memory;
  LimitOverrides o = limit_overrides_from_env();
  auto lower = [](std::optional<uint64_t>& a, const std::optional<uint64_t>& b) {
    if (b) a = a ? std::min(*a, *b) : *b;
  };
  lower(o.binding, extra.binding);
  lower(o.texels, extra.texels);
  lower(o.alloc, extra.alloc);
  lower(o.groups, extra.groups);
  lower(o.memory, extra.memory);
  apply_limit_overrides(caps_, o);
}

Context::~Context() {
  release();
  validation_log::forget_source(this);
}

void Context::release() {
  // On its own device dvs waits for everything. On the application's, dvs submits only to the queue it was given
  // (uploads included), and that queue is drained rather than dvs's last ticket waited for: the application's
  // submissions may wait on dvs's timeline, and a driver may still touch it after they are seen complete. Mesa 22.3's
  // queue thread releases a submission's semaphore waits after signalling its fence, so an application that waited
  // for its fence and then destroyed dvs's context crashed in that thread now and then
  // (SceneDeviceMemoryTest.ImagesAreLeftInTheFinalLayoutAskedFor, three copies at once under synchronization
  // validation: 26 crashes in 1838 runs; with the drain 0 in 1807). It costs the destructor the application's last
  // work on that queue; the application's other queues are none of dvs's business.
  if (device_ && owns_device_) vkDeviceWaitIdle(device_);
  if (device_ && !owns_device_ && timeline_) drain_shared_queue();
  for (auto& [ticket, action] : pending_releases_) action();
  pending_releases_.clear();
  if (profiler_) profiler_->print_if_enabled();
  pipelines_.reset();
  transfer_.reset();
  allocator_.reset();
  if (timeline_) vkDestroySemaphore(device_, timeline_, nullptr);
  if (command_pool_) vkDestroyCommandPool(device_, command_pool_, nullptr);
  if (device_ && owns_device_) vkDestroyDevice(device_, nullptr);
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_ && owns_device_) vkDestroyInstance(instance_, nullptr);
  timeline_ = VK_NULL_HANDLE;
  command_pool_ = VK_NULL_HANDLE;
  device_ = VK_NULL_HANDLE;
  messenger_ = VK_NULL_HANDLE;
  instance_ = VK_NULL_HANDLE;
}

void Context::name_object(VkObjectType type, uint64_t handle, const std::string& name) const {
  if (!set_object_name_ || !device_ || !handle) return;
  VkDebugUtilsObjectNameInfoEXT info{VK_STRUCTURE_TYPE_DEBUG_UTILS_OBJECT_NAME_INFO_EXT};
  info.objectType = type;
  info.objectHandle = handle;
  info.pObjectName = name.c_str();
  set_object_name_(device_, &info);
}

std::vector<std::string> Context::validation_messages() const {
  std::lock_guard<std::mutex> lock(messages_mutex_);
  return messages_;
}

void Context::clear_validation_messages() {
  std::lock_guard<std::mutex> lock(messages_mutex_);
  messages_.clear();
  validation_log::clear(this);
}

void Context::add_validation_message(std::string msg) {
  std::lock_guard<std::mutex> lock(messages_mutex_);
  validation_log::add(this, msg);
  messages_.push_back(std::move(msg));
}

VkCommandBuffer Context::allocate_command_buffer() {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = command_pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VK_CHECK(vkAllocateCommandBuffers(device_, &ai, &cmd));
  return cmd;
}

}  // namespace dvs::vk
