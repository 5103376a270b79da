/* The C API compiled as C (C99): dvs/dvs.h must be a C header. Checks the calls that need no model: version, the
 * argument errors and their messages, a context and its timeline, option defaults, a job whose input is missing (its
 * status and message come back through dvs_job_result), and a context on a device the test creates itself (a scene
 * rendered there takes the application's queue lock; dvs destroys nothing of the application's; its renders into the
 * test's own buffers and image, ordered by semaphores both ways, equal the host render byte for byte). Exit status
 * 0 = every check passed. */
#include <stdio.h>
#include <string.h>

#include "dvs/dvs.h"

static int failures = 0;

#define CHECK(cond, ...)                          \
  do {                                            \
    if (!(cond)) {                                \
      ++failures;                                 \
      printf("FAIL %s:%d: ", __FILE__, __LINE__); \
      printf(__VA_ARGS__);                        \
      printf("\n");                               \
    }                                             \
  } while (0)

static void lock_nothing(void* user) { (void)user; }

static int contains(const char* text, const char* part) { return text && strstr(text, part) != NULL; }

static int locks = 0;
static void count_lock(void* user) { ++*(int*)user; }

/* A host-visible, coherent buffer (mapped into *data) or a device-local optimal image of the test's device. */
static uint32_t memory_type(VkPhysicalDevice gpu, uint32_t bits, VkMemoryPropertyFlags want) {
  VkPhysicalDeviceMemoryProperties mem;
  uint32_t t;
  vkGetPhysicalDeviceMemoryProperties(gpu, &mem);
  for (t = 0; t < mem.memoryTypeCount; ++t)
    if (((bits >> t) & 1) && (mem.memoryTypes[t].propertyFlags & want) == want) return t;
  return 0;
}

static VkBuffer mapped_buffer(VkPhysicalDevice gpu, VkDevice device, VkDeviceSize bytes, VkDeviceMemory* memory,
                              void** data) {
  VkBufferCreateInfo bci = {VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  VkMemoryAllocateInfo mai = {VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  VkMemoryRequirements req;
  VkBuffer buffer = VK_NULL_HANDLE;
  bci.size = bytes;
  bci.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  vkCreateBuffer(device, &bci, NULL, &buffer);
  vkGetBufferMemoryRequirements(device, buffer, &req);
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = memory_type(gpu, req.memoryTypeBits,
                                    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  vkAllocateMemory(device, &mai, NULL, memory);
  vkBindBufferMemory(device, buffer, *memory, 0);
  vkMapMemory(device, *memory, 0, VK_WHOLE_SIZE, 0, data);
  memset(*data, 0, (size_t)bytes);
  return buffer;
}

static VkImage device_image(VkPhysicalDevice gpu, VkDevice device, VkFormat format, VkDeviceMemory* memory) {
  VkImageCreateInfo ci = {VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  VkMemoryAllocateInfo mai = {VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  VkMemoryRequirements req;
  VkImage image = VK_NULL_HANDLE;
  ci.imageType = VK_IMAGE_TYPE_2D;
  ci.format = format;
  ci.extent.width = 8, ci.extent.height = 8, ci.extent.depth = 1;
  ci.mipLevels = 1, ci.arrayLayers = 1, ci.samples = VK_SAMPLE_COUNT_1_BIT;
  ci.tiling = VK_IMAGE_TILING_OPTIMAL;
  ci.usage = VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  vkCreateImage(device, &ci, NULL, &image);
  vkGetImageMemoryRequirements(device, image, &req);
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = memory_type(gpu, req.memoryTypeBits, 0);
  vkAllocateMemory(device, &mai, NULL, memory);
  vkBindImageMemory(device, image, *memory, 0);
  return image;
}

/* The device-memory calls on the 8x8 scene: a render into the test's buffers (waited for with dvs_context_wait),
 * a render into its RGBA8 image that first waits for the test's own semaphore (dvs_context_wait_before_next,
 * signalled from the host after the call returned), read back by the test's submission waiting on dvs's timeline;
 * both equal the host render `want` (u8 [8,8,4]) byte for byte. And the refusals: an sRGB image, a NULL ticket. */
static void device_memory_calls(VkPhysicalDevice gpu, VkDevice device, uint32_t family, dvs_context* ctx,
                                dvs_scene* scene, const double pose[16], const uint8_t* want, const float* want_mask) {
  VkDeviceMemory image_memory, mask_memory, back_memory, rgba_memory, srgb_memory;
  void *image_data, *mask_data, *back_data;
  VkBuffer image = mapped_buffer(gpu, device, 8 * 8 * 4, &image_memory, &image_data);
  VkBuffer mask = mapped_buffer(gpu, device, 8 * 8 * 4, &mask_memory, &mask_data);
  VkBuffer back = mapped_buffer(gpu, device, 8 * 8 * 4, &back_memory, &back_data);
  VkImage rgba = device_image(gpu, device, VK_FORMAT_R8G8B8A8_UNORM, &rgba_memory);
  VkImage srgb = device_image(gpu, device, VK_FORMAT_R8G8B8A8_SRGB, &srgb_memory);
  VkSemaphoreTypeCreateInfo type = {VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
  VkSemaphoreCreateInfo sci = {VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  VkSemaphoreSignalInfo signal = {VK_STRUCTURE_TYPE_SEMAPHORE_SIGNAL_INFO};
  VkSemaphore app_semaphore = VK_NULL_HANDLE, timeline = VK_NULL_HANDLE;
  VkCommandPoolCreateInfo pci = {VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBufferAllocateInfo cai = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VkCommandBufferBeginInfo bi = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  VkBufferImageCopy region;
  VkTimelineSemaphoreSubmitInfo tsi = {VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
  VkPipelineStageFlags stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
  VkSubmitInfo si = {VK_STRUCTURE_TYPE_SUBMIT_INFO};
  VkQueue queue = VK_NULL_HANDLE;
  dvs_device_image target;
  uint64_t ticket = 0, second = 0, submitted = 0;
  int32_t reached = 0;

  CHECK(dvs_scene_render_to_buffers(scene, pose, image, 0, DVS_U8, mask, 0, &ticket) == DVS_OK,
        "render_to_buffers: %s", dvs_last_error());
  CHECK(dvs_context_submitted_value(ctx, &submitted) == DVS_OK && submitted == ticket && ticket > 0,
        "submitted value %llu, ticket %llu", (unsigned long long)submitted, (unsigned long long)ticket);
  CHECK(dvs_context_wait(ctx, ticket, UINT64_MAX, &reached) == DVS_OK && reached == 1, "wait: %s", dvs_last_error());
  CHECK(memcmp(image_data, want, 8 * 8 * 4) == 0, "the RGBA8 buffer differs from the host render");
  CHECK(memcmp(mask_data, want_mask, 8 * 8 * 4) == 0, "the mask buffer differs from the host render");

  /* Into the image, after the application's semaphore reaches 1 (signalled only once the call has returned: the
   * call does not wait for it). */
  type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
  sci.pNext = &type;
  vkCreateSemaphore(device, &sci, NULL, &app_semaphore);
  CHECK(dvs_context_wait_before_next(ctx, app_semaphore, 1) == DVS_OK, "wait_before_next: %s", dvs_last_error());
  memset(&target, 0, sizeof target);
  target.image = rgba;
  target.format = VK_FORMAT_R8G8B8A8_UNORM;
  target.width = 8, target.height = 8;
  target.layout = VK_IMAGE_LAYOUT_UNDEFINED;
  target.final_layout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
  CHECK(dvs_scene_render_to_images(scene, pose, &target, NULL, &second) == DVS_OK, "render_to_images: %s",
        dvs_last_error());
  CHECK(second > ticket, "the second ticket %llu is not after the first %llu", (unsigned long long)second,
        (unsigned long long)ticket);
  signal.semaphore = app_semaphore;
  signal.value = 1;
  vkSignalSemaphore(device, &signal);

  /* The application's read-back waits for dvs's ticket on the timeline (nothing on the host in between). */
  dvs_context_timeline(ctx, &timeline);
  pci.queueFamilyIndex = family;
  vkCreateCommandPool(device, &pci, NULL, &pool);
  cai.commandPool = pool, cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY, cai.commandBufferCount = 1;
  vkAllocateCommandBuffers(device, &cai, &cmd);
  vkBeginCommandBuffer(cmd, &bi);
  memset(&region, 0, sizeof region);
  region.imageSubresource.aspectMask = VK_IMAGE_ASPECT_COLOR_BIT;
  region.imageSubresource.layerCount = 1;
  region.imageExtent.width = 8, region.imageExtent.height = 8, region.imageExtent.depth = 1;
  vkCmdCopyImageToBuffer(cmd, rgba, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, back, 1, &region);
  vkEndCommandBuffer(cmd);
  tsi.waitSemaphoreValueCount = 1;
  tsi.pWaitSemaphoreValues = &second;
  si.pNext = &tsi;
  si.waitSemaphoreCount = 1;
  si.pWaitSemaphores = &timeline;
  si.pWaitDstStageMask = &stage;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  vkGetDeviceQueue(device, family, 0, &queue);
  CHECK(vkQueueSubmit(queue, 1, &si, VK_NULL_HANDLE) == VK_SUCCESS, "the test's read-back submission");
  vkQueueWaitIdle(queue);
  CHECK(memcmp(back_data, want, 8 * 8 * 4) == 0, "the RGBA8 image differs from the host render");

  /* Refusals name what is wrong. */
  target.image = srgb;
  target.format = VK_FORMAT_R8G8B8A8_SRGB;
  CHECK(dvs_scene_render_to_images(scene, pose, &target, NULL, &second) == DVS_ERROR_INVALID_ARGUMENT &&
            contains(dvs_last_error(), "sRGB"), "sRGB image: %s", dvs_last_error());
  CHECK(dvs_scene_render_to_buffers(scene, pose, image, 0, DVS_U8, VK_NULL_HANDLE, 0, NULL) ==
            DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "ticket is NULL"), "NULL ticket: %s",
        dvs_last_error());
  CHECK(dvs_context_wait_before_next(ctx, VK_NULL_HANDLE, 1) == DVS_ERROR_INVALID_ARGUMENT, "NULL semaphore");

  vkDestroyCommandPool(device, pool, NULL);
  vkDestroySemaphore(device, app_semaphore, NULL);
  vkDestroyImage(device, rgba, NULL);
  vkDestroyImage(device, srgb, NULL);
  vkDestroyBuffer(device, image, NULL);
  vkDestroyBuffer(device, mask, NULL);
  vkDestroyBuffer(device, back, NULL);
  vkFreeMemory(device, image_memory, NULL);
  vkFreeMemory(device, mask_memory, NULL);
  vkFreeMemory(device, back_memory, NULL);
  vkFreeMemory(device, rgba_memory, NULL);
  vkFreeMemory(device, srgb_memory, NULL);
}

/* The application's side: its own instance and device (Vulkan 1.2, timelineSemaphore), handed to dvs with a queue
 * lock that counts its calls; a scene rendered there must take the lock around its submissions. */
static void host_device_round_trip(void) {
  VkApplicationInfo app = {VK_STRUCTURE_TYPE_APPLICATION_INFO};
  VkInstanceCreateInfo ici = {VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice gpus[8];
  uint32_t gpu_count = 8, family_count = 16, family = UINT32_MAX, i;
  VkQueueFamilyProperties families[16];
  VkPhysicalDeviceVulkan12Features f12 = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  float priority = 1.0f;
  VkDeviceQueueCreateInfo qci = {VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  VkDeviceCreateInfo dci = {VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  VkDevice device = VK_NULL_HANDLE;
  dvs_host_device host;
  dvs_context* ctx = NULL;
  dvs_scene* scene = NULL;
  dvs_intrinsics k;
  uint8_t frame[8 * 8 * 3];
  float depth[8 * 8], image[3 * 8 * 8], mask[8 * 8];
  uint8_t rgba[8 * 8 * 4];
  const double moved[16] = {1, 0, 0, -0.05, 0, 1, 0, 0.02, 0, 0, 1, 0, 0, 0, 0, 1};
  float want;
  const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  dvs_status status;

  app.apiVersion = VK_API_VERSION_1_2;
  ici.pApplicationInfo = &app;
  if (vkCreateInstance(&ici, NULL, &instance) != VK_SUCCESS ||
      vkEnumeratePhysicalDevices(instance, &gpu_count, gpus) < 0 || gpu_count == 0) {
    CHECK(0, "the test's own Vulkan instance");
    return;
  }
  vkGetPhysicalDeviceQueueFamilyProperties(gpus[0], &family_count, families);
  for (i = 0; i < family_count && family == UINT32_MAX; ++i)
    if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) family = i;
  qci.queueFamilyIndex = family;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  f12.timelineSemaphore = VK_TRUE;
  dci.pNext = &f12;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  CHECK(vkCreateDevice(gpus[0], &dci, NULL, &device) == VK_SUCCESS, "the test's own device");

  memset(&host, 0, sizeof host);
  host.instance = instance;
  host.physical_device = gpus[0];
  host.device = device;
  host.queue_family = family;
  vkGetDeviceQueue(device, family, 0, &host.queue);
  host.instance_api_version = VK_API_VERSION_1_2;
  host.enabled_features = &f12;
  host.lock_queue = count_lock;
  host.unlock_queue = count_lock;
  host.user_data = &locks;
  status = dvs_context_create_on_host(&host, &ctx);
  CHECK(status == DVS_OK, "dvs_context_create_on_host: %d %s", (int)status, dvs_last_error());
  if (ctx) {
    for (i = 0; i < 8 * 8; ++i) {
      frame[3 * i] = (uint8_t)(4 * i), frame[3 * i + 1] = (uint8_t)(255 - 3 * i), frame[3 * i + 2] = (uint8_t)(i % 7);
      depth[i] = 0.5f + (float)i / 128.0f;
    }
    CHECK(dvs_intrinsics_default(8, 8, 0, &k) == DVS_OK, "intrinsics");
    status = dvs_scene_create(ctx, frame, DVS_U8, 8, 8, depth, &k, NULL, &scene);
    CHECK(status == DVS_OK, "scene on the host device: %s", dvs_last_error());
    if (scene) {
      status = dvs_scene_render(scene, identity, image, DVS_F32, mask);
      CHECK(status == DVS_OK, "render on the host device: %s", dvs_last_error());
      CHECK(locks > 0 && locks % 2 == 0, "the queue lock was called %d times (lock and unlock in pairs)", locks);
      /* At the identity a pixel is its input value (up to the splat's float rounding, far below an 8-bit step). */
      want = (float)frame[3 * 27] / 127.5f - 1.0f;
      CHECK(mask[27] == 1.0f && image[27] > want - 1e-3f && image[27] < want + 1e-3f, "pixel 27: %g, not %g (mask %g)",
            image[27], want, mask[27]);
      status = dvs_scene_render(scene, moved, rgba, DVS_U8, mask);
      CHECK(status == DVS_OK, "RGBA8 render on the host device: %s", dvs_last_error());
      device_memory_calls(gpus[0], device, family, ctx, scene, moved, rgba, mask);
    }
    CHECK(dvs_scene_destroy(scene) == DVS_OK, "scene destroy");
    CHECK(dvs_context_destroy(ctx) == DVS_OK, "context destroy");
  }
  /* dvs destroyed nothing of the application's: its device and instance are still ours to destroy. */
  if (device) vkDestroyDevice(device, NULL);
  vkDestroyInstance(instance, NULL);
}

int main(int argc, char** argv) {
  const char* dir = argc > 1 ? argv[1] : "/tmp";
  char path[1024];
  dvs_context* ctx = NULL;
  dvs_depth_estimator* estimator = NULL;
  dvs_render_options options;
  dvs_job* job = NULL;
  dvs_job_state state = DVS_JOB_RUNNING;
  dvs_status status;
  char name[256], error[1024];

  CHECK(strlen(dvs_version()) >= 5, "version \"%s\"", dvs_version());

  status = dvs_context_create(NULL, 0, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT, "NULL out: status %d", (int)status);
  CHECK(contains(dvs_last_error(), "dvs_context_create: out is NULL"), "message \"%s\"", dvs_last_error());

  {
    /* A host device with only one of the two queue-lock functions is refused before any Vulkan call. */
    dvs_host_device host;
    dvs_context* on_host = NULL;
    memset(&host, 0, sizeof host);
    host.lock_queue = lock_nothing;
    status = dvs_context_create_on_host(&host, &on_host);
    CHECK(status == DVS_ERROR_INVALID_ARGUMENT && on_host == NULL, "one lock function: status %d", (int)status);
    CHECK(contains(dvs_last_error(), "lock_queue and host->unlock_queue"), "message \"%s\"", dvs_last_error());
    status = dvs_context_create_on_host(NULL, &on_host);
    CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "host is NULL"), "NULL host: %d %s",
          (int)status, dvs_last_error());
  }

  {
    /* What a host device needs, before any context: the device this test makes enables Vulkan 1.2 and
     * timelineSemaphore, so both must be listed as required; the optional list is another one. */
    char required[4096], optional[4096], five[5] = "xxxx";
    size_t needed = 0, asked = 0;
    CHECK(dvs_context_requirements(0, required, sizeof required, &needed) == DVS_OK, "requirements: %s", dvs_last_error());
    CHECK(needed == strlen(required) + 1, "needed %zu for %zu characters", needed, strlen(required));
    CHECK(dvs_context_requirements(1, optional, sizeof optional, NULL) == DVS_OK, "options: %s", dvs_last_error());
    CHECK(contains(required, "Vulkan 1.2") && contains(required, "timelineSemaphore\n"), "required: \"%s\"", required);
    CHECK(!contains(optional, "timelineSemaphore") && strcmp(required, optional) != 0, "optional: \"%s\"", optional);
    CHECK(dvs_context_requirements(0, NULL, 8, NULL) == DVS_ERROR_INVALID_ARGUMENT, "NULL buffer accepted");
    /* The size query, and a buffer too small: refused with the size it needs, holding the text cut short. */
    CHECK(dvs_context_requirements(0, NULL, 0, &asked) == DVS_OK && asked == needed, "size query: %zu", asked);
    asked = 0;
    CHECK(dvs_context_requirements(0, five, sizeof five, &asked) == DVS_ERROR_INVALID_ARGUMENT && asked == needed &&
              strncmp(five, required, 4) == 0 && five[4] == '\0',
          "5-byte buffer: needed %zu, \"%s\", %s", asked, five, dvs_last_error());
    CHECK(contains(dvs_last_error(), "holds 5 bytes") && contains(dvs_last_error(), "needs"), "message \"%s\"",
          dvs_last_error());
  }

  status = dvs_context_create(NULL, 0, &ctx);
  CHECK(status == DVS_OK && ctx != NULL, "dvs_context_create: %d %s", (int)status, dvs_last_error());
  if (!ctx) return 1;
  CHECK(dvs_context_device_name(ctx, name, sizeof name, NULL) == DVS_OK && name[0] != '\0', "device name");
  printf("device: %s\n", name);
  /* A buffer too small for the name is filled and terminated, not overrun, and the call says what it needs. */
  {
    size_t needed = 0;
    const size_t length = strlen(name);
    name[3] = 'x';
    CHECK(dvs_context_device_name(ctx, name, 3, &needed) == DVS_ERROR_INVALID_ARGUMENT && strlen(name) == 2 &&
              name[3] == 'x' && needed == length + 1,
          "truncation: needed %zu", needed);
  }

  {
    /* The timeline semaphore exists from the start; value 0 is reached at once. */
    VkSemaphore timeline = VK_NULL_HANDLE;
    int32_t reached = 0;
    CHECK(dvs_context_timeline(ctx, &timeline) == DVS_OK && timeline != VK_NULL_HANDLE, "timeline: %s", dvs_last_error());
    CHECK(dvs_context_wait(ctx, 0, 0, &reached) == DVS_OK && reached == 1, "wait(0): %d %s", (int)reached,
          dvs_last_error());
  }

  snprintf(path, sizeof path, "%s/none.pth", dir);
  status = dvs_depth_estimator_create(ctx, path, 0, -1, &estimator);
  CHECK(status == DVS_ERROR_FILE && estimator == NULL, "missing model: status %d", (int)status);
  CHECK(contains(dvs_last_error(), "none.pth: no such depth model"), "message \"%s\"", dvs_last_error());
  status = dvs_depth_estimator_create(ctx, path, 0, 2, &estimator);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "metric must be"), "metric 2: %d %s",
        (int)status, dvs_last_error());

  CHECK(dvs_render_options_default(&options) == DVS_OK, "dvs_render_options_default");
  CHECK(options.frames == 49 && options.height == 480 && options.width == 720 &&
            strcmp(options.trajectory, "loop1") == 0 && options.depth_input_size == 518,
        "render defaults: %d %dx%d %s %d", options.frames, options.height, options.width, options.trajectory,
        options.depth_input_size);

  snprintf(path, sizeof path, "%s/missing.mp4", dir);
  options.video = path;
  options.depth = path;
  options.out_dir = dir;
  CHECK(dvs_job_start_render(&options, &job) == DVS_OK && job != NULL, "start: %s", dvs_last_error());
  status = dvs_job_result(job);
  CHECK(status == DVS_ERROR_FILE, "failing job: status %d", (int)status);
  CHECK(contains(dvs_last_error(), "missing.mp4"), "failing job: message \"%s\"", dvs_last_error());
  CHECK(dvs_job_poll(job, &state) == DVS_OK && state == DVS_JOB_FAILED, "failing job: state %d", (int)state);
  CHECK(dvs_job_error(job, error, sizeof error, NULL) == DVS_OK && contains(error, "missing.mp4"), "job error \"%s\"",
        error);
  CHECK(dvs_job_destroy(job) == DVS_OK, "dvs_job_destroy");
  CHECK(dvs_job_destroy(NULL) == DVS_OK, "destroying NULL");

  status = dvs_job_poll(NULL, &state);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_job_poll: job is NULL"),
        "NULL job: %d %s", (int)status, dvs_last_error());

  CHECK(dvs_context_destroy(ctx) == DVS_OK, "dvs_context_destroy");
  host_device_round_trip();
  printf("%s\n", failures ? "FAILED" : "all checks passed");
  return failures ? 1 : 0;
}
