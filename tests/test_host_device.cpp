// dvs on the application's Vulkan device (issue 22, item 2). The test plays the application: it creates its own
// instance (validation layer with synchronization validation, and a messenger that records every message) and
// device, hands them to dvs::Context, runs dvs work on them and checks by value what the application sees: results
// in its buffers after waiting for dvs's ticket on the host or on its own queue, dvs waiting for the application's
// semaphore, its queue lock taken around every submission, and its device still working after dvs is gone.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <string>
#include <thread>
#include <vector>

#include "dvs/context.hpp"
#include "dvs/error.hpp"
#include "embed/device_copy.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"

namespace dvs {
namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL record_message(VkDebugUtilsMessageSeverityFlagBitsEXT, VkDebugUtilsMessageTypeFlagsEXT,
                                              const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  static_cast<std::vector<std::string>*>(user)->push_back(data && data->pMessage ? data->pMessage : "");
  return VK_FALSE;
}

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS) throw std::runtime_error(std::string("test application: ") + what + " failed: " + std::to_string(r));
}

// What the application enables on its device.
struct AppFeatures {
  bool timeline_semaphore = true;
  bool float16 = false;
  bool memory_model_without_device_scope = false;
};

// The application: its instance, device and queue, and host-visible buffers it reads and writes itself.
class App {
 public:
  explicit App(AppFeatures features = {}) {
    VkApplicationInfo ai{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    ai.pApplicationName = "dvs host-device test";
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
    check(vkCreateInstance(&ici, nullptr, &instance), "vkCreateInstance with the validation layer");
    VkDebugUtilsMessengerCreateInfoEXT mci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    mci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    mci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT;
    mci.pfnUserCallback = record_message;
    mci.pUserData = &messages;
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    check(create(instance, &mci, nullptr, &messenger), "vkCreateDebugUtilsMessengerEXT");

    // The device the rest of the suite uses (DVS_DEVICE, else the best GPU).
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
    check(vkCreateDevice(physical, &dci, nullptr, &device), "vkCreateDevice");
    vkGetDeviceQueue(device, family, 0, &queue);
    VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pci.queueFamilyIndex = family;
    check(vkCreateCommandPool(device, &pci, nullptr, &pool), "vkCreateCommandPool");
  }

  ~App() {
    for (auto& b : buffers) {
      vkDestroyBuffer(device, b.buffer, nullptr);
      vkFreeMemory(device, b.memory, nullptr);
    }
    for (VkSemaphore s : semaphores) vkDestroySemaphore(device, s, nullptr);
    vkDestroyCommandPool(device, pool, nullptr);
    vkDestroyDevice(device, nullptr);
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
    destroy(instance, messenger, nullptr);
    vkDestroyInstance(instance, nullptr);
  }

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

  struct HostBuffer {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    float* data = nullptr;
  };
  // A host-visible, coherent buffer of `count` floats the application maps.
  HostBuffer& buffer(size_t count) {
    HostBuffer b;
    VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bci.size = count * sizeof(float);
    bci.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    check(vkCreateBuffer(device, &bci, nullptr, &b.buffer), "vkCreateBuffer");
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device, b.buffer, &req);
    VkPhysicalDeviceMemoryProperties mem{};
    vkGetPhysicalDeviceMemoryProperties(physical, &mem);
    const VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    uint32_t type = 0;
    while (!((req.memoryTypeBits >> type) & 1) || (mem.memoryTypes[type].propertyFlags & want) != want) ++type;
    VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    mai.allocationSize = req.size;
    mai.memoryTypeIndex = type;
    check(vkAllocateMemory(device, &mai, nullptr, &b.memory), "vkAllocateMemory");
    check(vkBindBufferMemory(device, b.buffer, b.memory, 0), "vkBindBufferMemory");
    void* p = nullptr;
    check(vkMapMemory(device, b.memory, 0, VK_WHOLE_SIZE, 0, &p), "vkMapMemory");
    b.data = static_cast<float*>(p);
    std::memset(p, 0, count * sizeof(float));
    buffers.push_back(b);
    return buffers.back();
  }

  VkSemaphore timeline_semaphore() {
    VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
    type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
    VkSemaphoreCreateInfo sci{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO, &type};
    VkSemaphore s = VK_NULL_HANDLE;
    check(vkCreateSemaphore(device, &sci, nullptr, &s), "vkCreateSemaphore");
    semaphores.push_back(s);
    return s;
  }

  // The application's own submission: copies `bytes` from `src` to `dst` after `wait` reaches `value` (no wait
  // when `wait` is null) and waits for it with a fence.
  void copy_on_app_queue(VkBuffer src, VkBuffer dst, VkDeviceSize bytes, VkSemaphore wait = VK_NULL_HANDLE,
                         uint64_t value = 0) {
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    check(vkAllocateCommandBuffers(device, &ai, &cmd), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    check(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
    VkBufferCopy region{0, 0, bytes};
    vkCmdCopyBuffer(cmd, src, dst, 1, &region);
    VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr,
                         0, nullptr);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    VkTimelineSemaphoreSubmitInfo tsi{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
    tsi.waitSemaphoreValueCount = 1;
    tsi.pWaitSemaphoreValues = &value;
    VkPipelineStageFlags stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    if (wait) {
      si.pNext = &tsi;
      si.waitSemaphoreCount = 1;
      si.pWaitSemaphores = &wait;
      si.pWaitDstStageMask = &stage;
    }
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd;
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence = VK_NULL_HANDLE;
    check(vkCreateFence(device, &fci, nullptr, &fence), "vkCreateFence");
    check(vkQueueSubmit(queue, 1, &si, fence), "vkQueueSubmit (application)");
    check(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
    vkDestroyFence(device, fence, nullptr);
    vkFreeCommandBuffers(device, pool, 1, &cmd);
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
  std::deque<HostBuffer> buffers;  // references to its elements stay valid
  std::vector<VkSemaphore> semaphores;
  std::vector<std::string> messages;
  bool queue_locked = false;
  int locks = 0, unlocks = 0;
};

ContextOptions no_disk_cache() {
  ContextOptions o;
  o.pipeline_cache_file = "-";
  return o;
}

// Values whose 2x + 1 is exact in fp32, different at every index.
std::vector<float> ramp(size_t n, float start) {
  std::vector<float> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = start + 0.5f * float(i);
  return v;
}

TEST(HostDevice, RunsDvsWorkOnTheApplicationsDeviceAndLeavesItUsable) {
  App app;
  const size_t n = 1000;
  const std::vector<float> x = ramp(n, -7.0f);
  {
    Context ctx(app.host(), no_disk_cache());
    EXPECT_FALSE(ctx.owns_device());
    ASSERT_NE(ctx.timeline(), VK_NULL_HANDLE);
    vk::Context& v = ctx.internal();
    EXPECT_EQ(v.device(), app.device);
    Tensor tx = Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, x), "x");
    Tensor ty = Tensor::empty(v, {int64_t(n)}, DType::f32, "y");
    vk::Recorder rec(v);
    rec.begin();
    ops::scale(rec, tx, ty, 2.0f, 1.0f);
    rec.end();
    rec.submit();
    const std::vector<float> y = ty.download(v).to_f32();
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(y[i], 2.0f * x[i] + 1.0f) << "element " << i;
    EXPECT_GT(ctx.submitted_value(), 0u);
    EXPECT_TRUE(ctx.wait(ctx.submitted_value(), 0));
    EXPECT_EQ(v.completed_value(), ctx.submitted_value());
  }
  // Every submission under the application's lock, in pairs (a lost unlock would also fail try_lock above).
  EXPECT_GE(app.locks, 1);
  EXPECT_EQ(app.locks, app.unlocks);

  // dvs is gone; the application's device, queue and pool still work.
  App::HostBuffer& a = app.buffer(64);
  App::HostBuffer& b = app.buffer(64);
  for (int i = 0; i < 64; ++i) a.data[i] = float(i * 3);
  app.copy_on_app_queue(a.buffer, b.buffer, 64 * sizeof(float));
  for (int i = 0; i < 64; ++i) ASSERT_EQ(b.data[i], float(i * 3));
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, CopiesATensorIntoTheApplicationsBufferOrderedByTheTicket) {
  App app;
  const size_t n = 4096;
  const std::vector<float> first = ramp(n, 3.0f), second = ramp(n, -100.0f);
  {
    Context ctx(app.host(), no_disk_cache());
    vk::Context& v = ctx.internal();
    App::HostBuffer& out = app.buffer(n);
    const DeviceBufferView view{out.buffer, 0, ElementType::f32, {int64_t(n)}};

    // Waited for on the host: the application reads the values once the ticket is reached.
    const uint64_t before = ctx.submitted_value();
    const uint64_t t1 = embed::copy_from_tensor(v, Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, first)), view,
                                                "the test's output");
    EXPECT_GT(t1, before);
    EXPECT_EQ(ctx.submitted_value(), t1);
    ASSERT_TRUE(ctx.wait(t1));
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(out.data[i], first[i]) << "element " << i;

    // Waited for on the application's queue: its copy waits for the ticket on dvs's timeline, nothing on the host.
    App::HostBuffer& mirror = app.buffer(n);
    const uint64_t t2 = embed::copy_from_tensor(v, Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, second)),
                                                view, "the test's output");
    app.copy_on_app_queue(out.buffer, mirror.buffer, n * sizeof(float), ctx.timeline(), t2);
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(mirror.data[i], second[i]) << "element " << i;
    EXPECT_TRUE(ctx.wait(t2));

    // dvs's compute result straight into the application's buffer, by value. (lavapipe runs in order, and
    // synchronization validation does not flag a missing barrier across a host-waited submission: tried by
    // removing it, 2026-11-27; the barriers follow the spec but no test here proves them.)
    Tensor x = Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, first));
    Tensor y = Tensor::empty(v, {int64_t(n)}, DType::f32, "y");
    vk::Recorder rec(v);
    rec.begin();
    ops::scale(rec, x, y, 2.0f, 1.0f);
    rec.end();
    rec.submit();
    ASSERT_TRUE(ctx.wait(embed::copy_from_tensor(v, y, view, "the test's output")));
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(out.data[i], 2.0f * first[i] + 1.0f) << "element " << i;
  }
  EXPECT_EQ(app.locks, app.unlocks);
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, NextSubmissionWaitsForTheApplicationsSemaphore) {
  App app;
  const size_t n = 512;
  const std::vector<float> written_later = ramp(n, 11.0f);
  {
    Context ctx(app.host(), no_disk_cache());
    vk::Context& v = ctx.internal();
    App::HostBuffer& in = app.buffer(n);  // zeros until the application writes it below
    VkSemaphore ready = app.timeline_semaphore();
    Tensor t = Tensor::zeros(v, {int64_t(n)}, DType::f32, "copy target");

    ctx.wait_before_next(ready, 1);
    const uint64_t ticket =
        embed::copy_to_tensor(v, {in.buffer, 0, ElementType::f32, {int64_t(n)}}, t, "the test's input");
    // Submitted, but held back by the application's semaphore.
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_FALSE(ctx.wait(ticket, 20'000'000)) << "dvs's copy ran before the application signalled";
    EXPECT_LT(v.completed_value(), ticket);

    // The application fills its buffer on the host, then signals.
    std::memcpy(in.data, written_later.data(), n * sizeof(float));
    VkSemaphoreSignalInfo signal{VK_STRUCTURE_TYPE_SEMAPHORE_SIGNAL_INFO};
    signal.semaphore = ready;
    signal.value = 1;
    ASSERT_EQ(vkSignalSemaphore(app.device, &signal), VK_SUCCESS);
    ASSERT_TRUE(ctx.wait(ticket));
    const std::vector<float> got = t.download(v).to_f32();
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(got[i], written_later[i]) << "element " << i;

    // The wait applied to one submission only: the next one runs at once.
    const uint64_t next = embed::copy_to_tensor(v, {in.buffer, 0, ElementType::f32, {int64_t(n)}}, t, "the input");
    EXPECT_TRUE(ctx.wait(next, 5'000'000'000ull));
  }
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, DeviceWithoutTimelineSemaphoreIsRefusedByName) {
  App app(AppFeatures{.timeline_semaphore = false});
  test::expect_error([&] { Context ctx(app.host(), no_disk_cache()); },
                     {"timelineSemaphore", "VkPhysicalDeviceVulkan12Features::timelineSemaphore = VK_TRUE"});
  // Every missing item at once: also a queue family without compute (an index past the last family).
  HostDevice bad = app.host();
  bad.queue_family = 99;
  bad.instance_api_version = VK_API_VERSION_1_1;
  test::expect_error([&] { Context ctx(bad, no_disk_cache()); },
                     {"timelineSemaphore", "VK_QUEUE_COMPUTE_BIT", "Vulkan 1.2", "instance_api_version"});
  // The memory model on without its device scope: dvs's device-scope atomics would be invalid.
  VkPhysicalDeviceVulkan12Features has12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 has{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &has12};
  vkGetPhysicalDeviceFeatures2(app.physical, &has);
  if (has12.vulkanMemoryModel) {
    App memory_model(AppFeatures{.memory_model_without_device_scope = true});
    test::expect_error([&] { Context ctx(memory_model.host(), no_disk_cache()); },
                       {"vulkanMemoryModelDeviceScope = VK_TRUE"});
    EXPECT_TRUE(memory_model.messages.empty()) << memory_model.first_message();
  }
  HostDevice none;
  test::expect_error([&] { Context ctx(none, no_disk_cache()); },
                     {"HostDevice::instance", "HostDevice::physical_device", "HostDevice::device", "HostDevice::queue"});
  // The refused device is the application's, untouched.
  App::HostBuffer& a = app.buffer(16);
  App::HostBuffer& b = app.buffer(16);
  for (int i = 0; i < 16; ++i) a.data[i] = float(i + 1);
  app.copy_on_app_queue(a.buffer, b.buffer, 16 * sizeof(float));
  for (int i = 0; i < 16; ++i) ASSERT_EQ(b.data[i], float(i + 1));
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, UsesOnlyWhatTheApplicationEnabled) {
  const vk::DeviceCaps& offered = test::gpu().caps();  // dvs's own device enables all it can
  {
    App app;  // float16 off
    Context ctx(app.host(), no_disk_cache());
    EXPECT_FALSE(ctx.internal().caps().float16_arithmetic);
    EXPECT_FALSE(ctx.internal().caps().float32_atomic_add);  // VK_EXT_shader_atomic_float not enabled
    EXPECT_FALSE(ctx.internal().caps().cooperative_matrix);
    EXPECT_FALSE(ctx.internal().caps().subgroup_size_control);
  }
  if (offered.float16_arithmetic) {
    App app(AppFeatures{.float16 = true});
    Context ctx(app.host(), no_disk_cache());
    EXPECT_TRUE(ctx.internal().caps().float16_arithmetic);
  }
  const auto required = Context::required_features();
  EXPECT_NE(std::find(required.begin(), required.end(), "timelineSemaphore"), required.end());
  EXPECT_FALSE(Context::optional_features().empty());
}

TEST(HostDevice, DeviceViewsAreCheckedAndNamed) {
  App app;
  Context ctx(app.host(), no_disk_cache());
  vk::Context& v = ctx.internal();
  App::HostBuffer& small = app.buffer(1);
  Tensor t = Tensor::zeros(v, {4, 4}, DType::f32, "t");
  Tensor big = Tensor::zeros(v, {64, 64}, DType::f32, "big");
  const uint64_t before = ctx.submitted_value();  // the zero fills
  test::expect_error([&] { embed::copy_to_tensor(v, {small.buffer, 0, ElementType::f32, {16}}, t, "the frame"); },
                     {"the frame", "f32[16]", "f32[4x4]"});
  test::expect_error([&] { embed::copy_to_tensor(v, {small.buffer, 0, ElementType::u8, {4, 4}}, t, "the mask"); },
                     {"the mask", "u8[4x4]", "f32[4x4]"});
  test::expect_error([&] { embed::copy_to_tensor(v, {small.buffer, 2, ElementType::f32, {4, 4}}, t, "the depth"); },
                     {"the depth", "multiple of 4"});
  test::expect_error([&] { embed::copy_from_tensor(v, big, {small.buffer, 0, ElementType::f32, {64, 64}}, "the output"); },
                     {"the output", "at most"});
  test::expect_error([&] { embed::copy_from_tensor(v, t, {VK_NULL_HANDLE, 0, ElementType::f32, {4, 4}}, "the output"); },
                     {"the output", "VK_NULL_HANDLE"});
  EXPECT_EQ(ctx.submitted_value(), before) << "a refused copy was submitted";
  test::expect_error([&] { ctx.wait(before + 5); }, {std::to_string(before + 5), "never"});
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

// dvs's own device (what the rest of the suite uses) has the timeline too: tickets count submissions, and what
// release_after holds is released once its ticket is reached.
class OwnDeviceTimeline : public test::GpuTest {};

TEST_F(OwnDeviceTimeline, TicketsCountSubmissionsAndReleaseAfterRuns) {
  vk::Context& v = ctx();
  ASSERT_NE(v.timeline(), VK_NULL_HANDLE);
  const uint64_t before = v.submission_count();
  const std::vector<float> values{1, 2, 3};
  Tensor t = Tensor::upload(v, HostTensor::from_f32({3}, values));
  Tensor u = Tensor::zeros(v, {3}, DType::f32);
  VkCommandBuffer cmd = v.allocate_command_buffer();
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  vkBeginCommandBuffer(cmd, &bi);
  VkBufferCopy region{t.buffer().offset, u.buffer().offset, t.bytes()};
  vkCmdCopyBuffer(cmd, t.buffer().buffer, u.buffer().buffer, 1, &region);
  VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       0, 1, &to_host, 0, nullptr, 0, nullptr);
  vkEndCommandBuffer(cmd);
  const uint64_t ticket = v.submit(cmd);
  EXPECT_EQ(ticket, v.submission_count());
  EXPECT_GT(ticket, before);
  bool released = false;
  v.release_after(ticket, [&] { released = true; });
  ASSERT_TRUE(v.wait(ticket));
  EXPECT_TRUE(released);
  EXPECT_EQ(u.download(v).to_f32(), (std::vector<float>{1, 2, 3}));
}

}  // namespace
}  // namespace dvs
