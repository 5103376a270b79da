/* The C API compiled as C (C99): dvs/dvs.h must be a C header. Checks the calls that need no model: version, the
 * argument errors and their messages, a context and its timeline, option defaults, a job whose input is missing (its
 * status and message come back through dvs_job_result), the option structs' struct_size (older, newer and unfilled
 * structs), negative numbers refused naming the field, the preflight's report and the size it needs, the log
 * callback, trajectories (load, interpolate, write and read back) and the memory plan of the built-in model, and a
 * context on a device the test creates itself (a scene
 * rendered there takes the application's queue lock; dvs destroys nothing of the application's; its renders into the
 * test's own buffers and image, ordered by semaphores both ways, equal the host render byte for byte). Exit status
 * 0 = every check passed. */
#define _POSIX_C_SOURCE 200809L /* mkdir */
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

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

/* ---- option structs, negatives, preflight, log, trajectories, plan (issue 34) ---------------------------- */

static int log_calls = 0;
static char log_last[4096];
static void capture_log(dvs_log_level level, const char* message, void* user) {
  ++*(int*)user;
  if (level == DVS_LOG_WARNING) snprintf(log_last, sizeof log_last, "%s", message);
}

/* The report of dvs_preflight_pipeline for options whose one number is out of range (the rest default; no model,
 * which is a problem of its own); status and problem count through the out arguments. */
static dvs_status preflight_text(const dvs_pipeline_options* o, int32_t* problems, char* report, size_t size) {
  size_t needed = 0;
  return dvs_preflight_pipeline(o, problems, report, size, &needed);
}

/* Item 7: steps, strength, delta, inversion_steps below 0 are refused naming the field (0 = the preset's). */
static void negatives_are_refused(void) {
  static const char* const fields[] = {"steps", "strength", "delta", "inversion_steps"};
  char report[8192], want[128];
  int32_t problems = 0;
  int i;
  dvs_pipeline_options o;
  dvs_job* job = NULL;
  for (i = 0; i < 4; ++i) {
    CHECK(dvs_pipeline_options_default(&o) == DVS_OK, "defaults");
    if (i == 0) o.steps = -3;
    if (i == 1) o.strength = -1;
    if (i == 2) o.delta = -1;
    if (i == 3) o.inversion_steps = -1;
    snprintf(want, sizeof want, "dvs_pipeline_options.%s is -%d", fields[i], i == 0 ? 3 : 1);
    CHECK(preflight_text(&o, &problems, report, sizeof report) == DVS_OK, "preflight: %s", dvs_last_error());
    CHECK(problems >= 1 && contains(report, want), "%s: %d problems, report \"%s\"", want, (int)problems, report);
    /* A job with it is refused when it starts, with the same words (an argument error, no job). */
    job = NULL;
    CHECK(dvs_job_start_pipeline(&o, &job) == DVS_ERROR_INVALID_ARGUMENT && job == NULL &&
              contains(dvs_last_error(), want),
          "start: \"%s\"", dvs_last_error());
    if (job) dvs_job_destroy(job);
  }
  /* A preset that does not exist names its field too. */
  CHECK(dvs_pipeline_options_default(&o) == DVS_OK, "defaults");
  o.preset = "Paper";
  CHECK(preflight_text(&o, &problems, report, sizeof report) == DVS_OK &&
            contains(report, "dvs_pipeline_options.preset must be paper or official, got 'Paper'"),
        "preset: \"%s\"", report);
  /* 0 asks for the preset's default: no problem names the field. */
  CHECK(dvs_pipeline_options_default(&o) == DVS_OK, "defaults");
  o.steps = 0, o.strength = 0, o.delta = 0, o.inversion_steps = 0;
  CHECK(preflight_text(&o, &problems, report, sizeof report) == DVS_OK, "preflight: %s", dvs_last_error());
  CHECK(!contains(report, "dvs_pipeline_options.steps") && !contains(report, "dvs_pipeline_options.strength") &&
            !contains(report, "dvs_pipeline_options.delta") && contains(report, "dvs_pipeline_options.model"),
        "zeros: \"%s\"", report);
}

/* struct_size: set by the defaults; 0 (a struct never filled) refused; a newer header's longer struct accepted when
 * its unknown fields are 0 and refused when one is set; a string report's needed size. */
static void grown_structs(const char* dir) {
  struct {
    dvs_render_options known;
    int64_t newer[2]; /* what a later dvs.h might add */
  } grown;
  dvs_render_options r;
  dvs_pipeline_options p;
  char video[1024], report[4096], small[8];
  size_t needed = 0, again = 0;
  int32_t problems = -1;
  dvs_status status;

  CHECK(dvs_render_options_default(&r) == DVS_OK && r.struct_size == sizeof r, "render struct_size %zu", r.struct_size);
  CHECK(dvs_pipeline_options_default(&p) == DVS_OK && p.struct_size == sizeof p && p.render == NULL &&
            p.dynamic_cfg == -1 && p.preservation_scale == 1.0 && p.vae_tiling == 0 && strcmp(p.weights, "auto") == 0,
        "pipeline defaults");
  CHECK(strcmp(r.depth_fit, "error") == 0 && r.export_glb == 1 && r.depth_cache == 1 && r.squash == 0, "render defaults");
  snprintf(video, sizeof video, "%s/no_such_video.mp4", dir);
  r.video = video;
  r.depth = video;
  r.out_dir = dir;

  /* The report: every problem as "problem: ...", the size it needs given even when it does not fit. */
  CHECK(dvs_preflight_render(&r, &problems, NULL, 0, &needed) == DVS_OK, "ask the size: %s", dvs_last_error());
  CHECK(problems >= 1 && needed > 1, "%d problems, %zu bytes needed", (int)problems, needed);
  CHECK(needed <= sizeof report && dvs_preflight_render(&r, NULL, report, sizeof report, &again) == DVS_OK &&
            again == needed && strlen(report) + 1 == needed,
        "report of %zu bytes, needed %zu then %zu", strlen(report), needed, again);
  CHECK(contains(report, "problem: ") && contains(report, "no_such_video.mp4: no such video file (give "
                                                          "dvs_render_options.video)"),
        "report \"%s\"", report);
  /* A short buffer is refused (the string calls' rule, dvs.h), holding the text cut short and saying what it needs. */
  CHECK(dvs_preflight_render(&r, NULL, small, sizeof small, &again) == DVS_ERROR_INVALID_ARGUMENT &&
            strlen(small) == 7 && again == needed,
        "a short buffer: \"%s\", needed %zu", small, again);

  r.struct_size = 0;
  status = dvs_preflight_render(&r, &problems, report, sizeof report, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_render_options.struct_size is 0") &&
            contains(dvs_last_error(), "dvs_render_options_default"),
        "struct_size 0: %d %s", (int)status, dvs_last_error());

  memset(&grown, 0, sizeof grown);
  CHECK(dvs_render_options_default(&grown.known) == DVS_OK, "defaults");
  grown.known = r;
  grown.known.struct_size = sizeof grown;
  CHECK(dvs_preflight_render(&grown.known, &problems, report, sizeof report, NULL) == DVS_OK && problems >= 1 &&
            contains(report, "no_such_video.mp4"),
        "a newer struct with its new fields 0: %s", dvs_last_error());
  grown.newer[1] = 5;
  status = dvs_preflight_render(&grown.known, &problems, report, sizeof report, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "newer than this library"),
        "a newer struct with a field set: %d %s", (int)status, dvs_last_error());

  /* The pipeline's render part is read through its own struct_size. */
  r.struct_size = 0;
  p.render = &r;
  status = dvs_preflight_pipeline(&p, &problems, report, sizeof report, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_render_options.struct_size is 0"),
        "pipeline with an unfilled render: %d %s", (int)status, dvs_last_error());
  p.render = NULL;
  p.struct_size = 3;
  status = dvs_preflight_pipeline(&p, &problems, report, sizeof report, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_pipeline_options.struct_size is 3"),
        "pipeline struct_size 3: %d %s", (int)status, dvs_last_error());
  p.struct_size = sizeof p;
  p.dynamic_cfg = 2;
  status = dvs_preflight_pipeline(&p, &problems, report, sizeof report, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_pipeline_options.dynamic_cfg must be"),
        "dynamic_cfg 2: %d %s", (int)status, dvs_last_error());
  /* weights: checked naming the field; a program built against the dvs.h before it (a shorter struct) gets "auto",
   * whatever lies beyond its struct. */
  p.dynamic_cfg = -1;
  p.weights = "sometimes";
  status = dvs_preflight_pipeline(&p, &problems, report, sizeof report, NULL);
  CHECK((status == DVS_ERROR_INVALID_ARGUMENT ? contains(dvs_last_error(), "dvs_pipeline_options.weights must be")
                                              : contains(report, "dvs_pipeline_options.weights must be")),
        "weights sometimes: %d %s %s", (int)status, dvs_last_error(), report);
  p.struct_size = offsetof(dvs_pipeline_options, weights);
  status = dvs_preflight_pipeline(&p, &problems, report, sizeof report, NULL);
  CHECK(status == DVS_OK && !contains(report, "weights"), "an older struct without weights: %d %s %s", (int)status,
        dvs_last_error(), report);
}

/* Trajectories: a preset, a written JSON read back exactly, key poses interpolated; an official .txt whose lines
 * differ in length is loaded with a warning that reaches the log callback. */
static void trajectories(const char* dir) {
  double poses[16 * 5], back[16 * 5], keys[16 * 2], path[16 * 5];
  const int32_t key_frames[2] = {0, 4};
  char file[1024];
  FILE* f;
  int i;
  dvs_status status;

  CHECK(dvs_trajectory_load("pan_left:30", 5, 1.0, poses, 16 * 5) == DVS_OK, "pan_left: %s", dvs_last_error());
  for (i = 0; i < 16; ++i) CHECK(poses[i] == (i % 5 == 0 ? 1.0 : 0.0), "pose 0 is not the identity at %d", i);
  CHECK(poses[16 * 4 + 15] == 1.0 && poses[16 * 4 + 0] < 0.99, "the last pose does not turn: %g", poses[16 * 4]);
  snprintf(file, sizeof file, "%s/path.json", dir);
  CHECK(dvs_trajectory_write_json(file, poses, 5, "a test path") == DVS_OK, "write json: %s", dvs_last_error());
  CHECK(dvs_trajectory_load(file, 5, 1.0, back, 16 * 5) == DVS_OK && memcmp(back, poses, sizeof poses) == 0,
        "the JSON does not read back exactly: %s", dvs_last_error());
  snprintf(file, sizeof file, "%s/path.glb", dir);
  CHECK(dvs_trajectory_write_glb(file, poses, 5, 24.0) == DVS_OK, "write glb: %s", dvs_last_error());
  CHECK(dvs_trajectory_load(file, 5, 1.0, back, 16 * 5) == DVS_OK, "read glb: %s", dvs_last_error());
  for (i = 0; i < 16 * 5; ++i) CHECK(back[i] > poses[i] - 1e-5 && back[i] < poses[i] + 1e-5, "glb value %d", i);

  /* Keys at frames 0 (identity) and 4 (moved 0.4 along x): frame 2 is halfway, frame 4 exactly the key. */
  memset(keys, 0, sizeof keys);
  for (i = 0; i < 4; ++i) keys[5 * i] = keys[16 + 5 * i] = 1.0;
  keys[16 + 3] = 0.4;
  CHECK(dvs_trajectory_interpolate(key_frames, keys, 2, 5, path, 16 * 5) == DVS_OK, "interpolate: %s", dvs_last_error());
  CHECK(path[16 * 2 + 3] > 0.2 - 1e-12 && path[16 * 2 + 3] < 0.2 + 1e-12 && memcmp(path + 16 * 4, keys + 16, 128) == 0,
        "interpolated: frame 2 x %g", path[16 * 2 + 3]);
  CHECK(dvs_trajectory_load("pan_left:30", 5, 1.0, poses, 16 * 4) == DVS_ERROR_INVALID_ARGUMENT &&
            contains(dvs_last_error(), "pose_doubles is 64 but 5 poses are 80 doubles"),
        "short buffer: %s", dvs_last_error());
  status = dvs_trajectory_load("nowhere_preset", 5, 1.0, poses, 16 * 5);
  CHECK(status != DVS_OK && contains(dvs_last_error(), "nowhere_preset"), "unknown: %s", dvs_last_error());

  snprintf(file, sizeof file, "%s/uneven.txt", dir);
  f = fopen(file, "w");
  if (f) {
    fputs("0 5 10\n0 -3\n0 0 0 0\n", f);
    fclose(f);
  }
  log_calls = 0;
  CHECK(dvs_set_log_callback(capture_log, &log_calls) == DVS_OK, "set log callback");
  CHECK(dvs_trajectory_load(file, 5, 1.0, poses, 16 * 5) == DVS_OK, "uneven: %s", dvs_last_error());
  CHECK(log_calls == 1 && contains(log_last, "uneven.txt: its lines hold different numbers of values"),
        "log: %d calls, last \"%s\"", log_calls, log_last);
  CHECK(dvs_set_log_callback(NULL, NULL) == DVS_OK, "the default log again");
  CHECK(dvs_trajectory_load(file, 5, 1.0, poses, 16 * 5) == DVS_OK && log_calls == 1,
        "the callback is still called after it was removed");
}

/* The memory plan of the built-in CogVideoX-5B-I2V: its weights and peak, the table and the JSON; a budget it does
 * not fit in is checked and refused; a wrong frame count names the field. */
static void memory_plan(void) {
  dvs_plan_request q;
  dvs_plan_result result;
  char table[65536];
  size_t needed = 0;
  dvs_status status;
  CHECK(dvs_plan_request_default(&q) == DVS_OK && q.frames == 49 && q.height == 480 && q.width == 720, "defaults");
  q.model = "cogvideox-5b-i2v";
  memset(&result, 0, sizeof result);
  result.struct_size = sizeof result;
  CHECK(dvs_plan_run_memory(&q, &result, 0, table, sizeof table, &needed) == DVS_OK, "plan: %s", dvs_last_error());
  CHECK(result.checked == 0 && result.runs == 1 && result.weights_bytes > ((uint64_t)10 << 30) &&
            result.run_peak_bytes > result.weights_bytes && needed == strlen(table) + 1,
        "plan: checked %d runs %d weights %llu peak %llu", (int)result.checked, (int)result.runs,
        (unsigned long long)result.weights_bytes, (unsigned long long)result.run_peak_bytes);
  /* 4 GiB runs with the weights streamed and 96x160 VAE tiles (peak 3.16 GiB: the streamed transformer's phase); 3 GiB
   * holds no setting. */
  q.budget = (uint64_t)4 << 30;
  CHECK(dvs_plan_run_memory(&q, &result, 0, table, sizeof table, NULL) == DVS_OK && result.checked == 1 &&
            result.runs == 1,
        "a 4 GiB budget: checked %d runs %d", (int)result.checked, (int)result.runs);
  q.budget = (uint64_t)3 << 30;
  CHECK(dvs_plan_run_memory(&q, &result, 1, table, sizeof table, NULL) == DVS_OK && result.checked == 1 &&
            result.runs == 0 && table[0] == '{',
        "a 3 GiB budget: checked %d runs %d", (int)result.checked, (int)result.runs);
  q.frames = 8;
  status = dvs_plan_run_memory(&q, &result, 0, table, sizeof table, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_plan_request.frames must be 4k+1"),
        "8 frames: %d %s", (int)status, dvs_last_error());
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
  mkdir(dir, 0755); /* the files this test writes (trajectories) go there; it may exist */

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
  negatives_are_refused();
  grown_structs(dir);
  trajectories(dir);
  memory_plan();
  host_device_round_trip();
  printf("%s\n", failures ? "FAILED" : "all checks passed");
  return failures ? 1 : 0;
}
