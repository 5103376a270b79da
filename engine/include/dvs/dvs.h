/* The dvs C API: the embedding calls of dvs (dvs/context.hpp, scene.hpp, depth_frames.hpp, job.hpp) for engines and
 * languages that cannot take C++ (Unity, Godot, Python through ctypes). C99; one header.
 *
 * Conventions:
 * - Every call returns a dvs_status (DVS_OK = 0) except dvs_version and dvs_last_error. On a failure,
 *   dvs_last_error() gives the message (which argument or file, what is wrong, what to do) of the last failed call
 *   on the calling thread; no C++ exception ever leaves a call.
 * - Handles (dvs_context, dvs_scene, dvs_depth_estimator, dvs_job) are opaque; the *_create / *_start calls return
 *   them through an out pointer, and only the matching *_destroy call frees them (destroying NULL is DVS_OK).
 *   Scenes and depth estimators keep their context's device objects alive: they still work after
 *   dvs_context_destroy, and the device objects go with the last of them (on the application's device, destroy
 *   every dvs handle made on it before its VkDevice). dvs_context_destroy cancels a job running on the context and
 *   waits for its end (its dvs_job_result is then DVS_ERROR_CANCELLED).
 * - Memory: dvs never keeps, frees or reallocates a pointer it is given; it reads inputs and writes outputs during
 *   the call only. Strings are copied into the caller's buffer (buffer, size, needed): *needed (when not NULL)
 *   receives the bytes the text needs, NUL included; a buffer too small holds the text cut short (NUL-terminated)
 *   and the call returns DVS_ERROR_INVALID_ARGUMENT; buffer NULL with size 0 asks for *needed alone (DVS_OK).
 * - Threads: calls on one context (and on what is made on it) from several threads are serialised: each waits for
 *   the one running. While a job runs on a context (dvs_job_start_pipeline_clip), a call on it from another thread
 *   is refused with DVS_ERROR_INVALID_ARGUMENT naming the job: for work beside a job (a preview render loop), make a
 *   second context on the same device (dvs_context_create again, or dvs_context_create_on_host with the same
 *   objects; docs/embedding.md). Distinct contexts are independent, also on one device and queue. A job runs on a
 *   thread of its own; its calls may come from any thread.
 * - Arrays are contiguous and row-major; "f32 [3,H,W]" is 3*H*W floats, channel-major.
 */
#ifndef DVS_H
#define DVS_H

#include <stddef.h>
#include <stdint.h>
#include <vulkan/vulkan.h>

#include "dvs/api.h"     /* DVS_API */
#include "dvs/version.h" /* DVS_VERSION_MAJOR, DVS_VERSION_MINOR, DVS_VERSION_PATCH */

#ifdef __cplusplus
extern "C" {
#endif

/* Each status but DVS_OK is one dvs::ErrorKind of the C++ API (dvs/error.hpp). */
typedef enum dvs_status {
  DVS_OK = 0,
  DVS_ERROR_INVALID_ARGUMENT = 1, /* an argument or option refused before any work: a NULL handle or pointer, a size,
                                     shape or type out of range, a bad pose or preset, a ticket never submitted, a
                                     buffer too small for a string, a context in use by a job (nothing was done) */
  DVS_ERROR_FILE = 2,             /* the work failed on its inputs: a file missing, unreadable or malformed, a model
                                     that does not fit the device, values refused (ErrorKind::input) */
  DVS_ERROR_DEVICE = 3,           /* the Vulkan device: none usable, a missing feature */
  DVS_ERROR_CANCELLED = 4,        /* stopped on request (a progress callback, dvs_job_cancel, dvs_context_destroy) */
  DVS_ERROR_OUT_OF_MEMORY = 5,    /* host or device memory ran out */
  DVS_ERROR_INTERNAL = 6,         /* a failure dvs does not expect (a bug: please report the message) */
  DVS_ERROR_DEVICE_LOST = 7       /* the device was lost (VK_ERROR_DEVICE_LOST): nothing on it survives */
} dvs_status;

typedef enum dvs_element_type { DVS_F32 = 0, DVS_U8 = 1 } dvs_element_type;

typedef struct dvs_context dvs_context;
typedef struct dvs_scene dvs_scene;
typedef struct dvs_depth_estimator dvs_depth_estimator;
typedef struct dvs_job dvs_job;

/* The library's version, "MAJOR.MINOR.PATCH" (static storage): the library loaded at run time, which
 * DVS_VERSION_MAJOR/MINOR/PATCH (dvs/version.h) give for the headers compiled against. */
DVS_API const char* dvs_version(void);
/* The message of the last failed call on this thread ("" when none failed yet). Valid until the next failing call
 * on this thread. */
DVS_API const char* dvs_last_error(void);

/* Progress of long calls, on the thread doing the work: stage ("depth", "render", "sample", ...), step (1-based) of
 * total (0 when the stage is not stepped), a note. Return nonzero to cancel (the call then ends with
 * DVS_ERROR_CANCELLED at its next check). `user` is what the caller passed with it. */
typedef int (*dvs_progress_fn)(const char* stage, int32_t step, int32_t total, const char* note, void* user);

/* ---- context: the Vulkan device dvs works on (dvs/context.hpp) ---------------------------------------------- */

/* dvs's own instance and device. device: index or name substring, NULL or "" = $DVS_DEVICE else the best GPU;
 * validation: nonzero enables the Khronos validation layer. *out receives the context. */
DVS_API dvs_status dvs_context_create(const char* device, int32_t validation, dvs_context** out);

/* The application's Vulkan objects (dvs::HostDevice). The device must be created with what
 * dvs::Context::required_features() lists (Vulkan 1.2, timelineSemaphore); the queue must come from queue_family
 * (compute and transfer). lock_queue/unlock_queue (both NULL, or both set) are called around every submission dvs
 * makes on `queue`, with user_data, for a queue the application also submits to from other threads. dvs never
 * destroys these objects. */
typedef struct dvs_host_device {
  VkInstance instance;
  VkPhysicalDevice physical_device;
  VkDevice device;
  uint32_t queue_family;
  VkQueue queue;
  uint32_t instance_api_version; /* VkApplicationInfo::apiVersion of the instance; >= VK_API_VERSION_1_2 */
  /* What the application enabled when it created the device (dvs cannot read it back): the VkDeviceCreateInfo::pNext
   * feature chain (read during dvs_context_create_on_host only) and the enabled extension names. */
  const void* enabled_features;
  const char* const* enabled_extensions;
  uint32_t enabled_extension_count;
  void (*lock_queue)(void* user_data);
  void (*unlock_queue)(void* user_data);
  void* user_data;
} dvs_host_device;

/* A context on the application's device. A missing feature or extension is DVS_ERROR_DEVICE naming each. */
DVS_API dvs_status dvs_context_create_on_host(const dvs_host_device* host, dvs_context** out);
DVS_API dvs_status dvs_context_destroy(dvs_context* context);
/* The device's name, copied into buffer (size bytes; *needed: the bytes it needs, NUL included). */
DVS_API dvs_status dvs_context_device_name(const dvs_context* context, char* buffer, size_t size, size_t* needed);
/* The timeline semaphore dvs signals after each submission (dvs::Context::timeline). */
DVS_API dvs_status dvs_context_timeline(const dvs_context* context, VkSemaphore* out);
/* Blocks until the timeline reaches ticket, at most timeout_ns; *reached (may be NULL) is 1 when it did, 0 when
 * the wait timed out. A ticket never submitted (it would never be reached) is DVS_ERROR_INVALID_ARGUMENT. */
DVS_API dvs_status dvs_context_wait(const dvs_context* context, uint64_t ticket, uint64_t timeout_ns, int32_t* reached);
/* What a device given to dvs_context_create_on_host must have been created with (optional = 0: "Vulkan 1.2",
 * "timelineSemaphore", ...; dvs::Context::required_features) or what dvs uses when it was (optional = 1: 16-bit
 * storage, ...; dvs::Context::optional_features): the names one per line, copied into buffer (size bytes; *needed:
 * the bytes they need, NUL included). Needs no context: ask before creating the device. */
DVS_API dvs_status dvs_context_requirements(int32_t optional, char* buffer, size_t size, size_t* needed);

/* ---- scene: the splat render of one frame from any pose (dvs/scene.hpp) ------------------------------------ */

/* Pixels of width x height, OpenCV convention (no +0.5). */
typedef struct dvs_intrinsics {
  double fx, fy, cx, cy;
  int32_t width, height;
} dvs_intrinsics;

/* What `dvs render` uses without --intrinsics (dvs::CameraIntrinsics::dvs_default); squash nonzero = the
 * official per-axis scaling. */
DVS_API dvs_status dvs_intrinsics_default(int32_t width, int32_t height, int32_t squash, dvs_intrinsics* out);

typedef struct dvs_scene_options {
  int32_t depth_is_disparity; /* nonzero: depth holds disparity (dvs depth, Video-Depth-Anything); 0: metric depth */
  int32_t hard_points;        /* nonzero: z-buffer point splat instead of the soft bilinear splat */
} dvs_scene_options;

/* Builds the point cloud of one frame. frame: DVS_U8 [H,W,3] RGB, or DVS_F32 [3,H,W] RGB in [-1,1]; depth: f32
 * [H,W]; intrinsics: of the frame (width = W, height = H); options: NULL = disparity, soft splat. Both arrays are
 * read during the call only. */
DVS_API dvs_status dvs_scene_create(dvs_context* context, const void* frame, dvs_element_type frame_type,
                                    int32_t height, int32_t width, const float* depth, const dvs_intrinsics* intrinsics,
                                    const dvs_scene_options* options, dvs_scene** out);
/* Renders from pose (16 doubles, row-major 4x4 world-to-camera transform T of the source camera's world; identity
 * = the input view) into image: DVS_F32 [3,H,W] in [-1,1] (holes -1), or DVS_U8 [H,W,4] RGBA (alpha 255 where
 * visible, holes 0,0,0,0). mask: f32 [H,W] (1 = visible), or NULL. Returns when done. */
DVS_API dvs_status dvs_scene_render(dvs_scene* scene, const double pose[16], void* image, dvs_element_type image_type,
                                    float* mask);
/* The official orbit radius of the frame (min(centre depth, 5)): the unit of dolly/truck presets. */
DVS_API dvs_status dvs_scene_orbit_radius(const dvs_scene* scene, double* out);
DVS_API dvs_status dvs_scene_destroy(dvs_scene* scene);

/* ---- the application's device memory: scene renders that never block, ordering with the application ------- */
/* (dvs/scene.hpp, dvs/views.hpp, dvs/context.hpp). A render into device memory returns *ticket, a value of the
 * context's timeline (dvs_context_timeline): the application waits for it on its own queue (a timeline-semaphore
 * wait in its submission) or on the host (dvs_context_wait). The call waits only for the previous render of the
 * same scene. Buffers and images must stay valid until the ticket is reached. */

/* Into VkBuffers (TRANSFER_DST usage, offsets multiples of 4): image DVS_F32 [3,H,W] or DVS_U8 [H,W,4] as
 * dvs_scene_render; mask f32 [H,W], or VK_NULL_HANDLE for none. */
DVS_API dvs_status dvs_scene_render_to_buffers(dvs_scene* scene, const double pose[16], VkBuffer image,
                                               VkDeviceSize image_offset, dvs_element_type image_type, VkBuffer mask,
                                               VkDeviceSize mask_offset, uint64_t* ticket);

/* A 2-D image of the context's device (dvs::DeviceImageView): one mip level, one layer, colour, TRANSFER_DST usage,
 * exclusive to the context's queue family or CONCURRENT. layout: what it is in when dvs's work starts (UNDEFINED =
 * contents may be discarded); final_layout: what dvs leaves it in (e.g. SHADER_READ_ONLY_OPTIMAL). */
typedef struct dvs_device_image {
  VkImage image;
  VkFormat format; /* VK_FORMAT_R8G8B8A8_UNORM for the image (not _SRGB), VK_FORMAT_R32_SFLOAT (1 = visible) or
                     VK_FORMAT_R8G8B8A8_UNORM (opaque white where visible, black elsewhere) for the mask */
  uint32_t width, height;
  VkImageLayout layout;
  VkImageLayout final_layout;
} dvs_device_image;

/* Into images of the scene's width x height: image RGBA8 (alpha 255 where visible), mask (NULL = none) 1 = visible. */
DVS_API dvs_status dvs_scene_render_to_images(dvs_scene* scene, const double pose[16], const dvs_device_image* image,
                                              const dvs_device_image* mask, uint64_t* ticket);

/* The last timeline value dvs has submitted (dvs::Context::submitted_value). */
DVS_API dvs_status dvs_context_submitted_value(const dvs_context* context, uint64_t* out);
/* dvs's next submission on this context waits until semaphore (a timeline semaphore of the same device) reaches
 * value: how the application orders its own writes of a buffer or image before dvs uses it. */
DVS_API dvs_status dvs_context_wait_before_next(dvs_context* context, VkSemaphore semaphore, uint64_t value);

/* ---- depth of frames in memory (dvs/depth_frames.hpp) ------------------------------------------------------ */

/* Loads a Video-Depth-Anything checkpoint (.pth, or a .safetensors of it) once. input_size: the network input's
 * short side, 0 = 518; metric: -1 = the checkpoint's mode, 0 = relative (disparity), 1 = metric. */
DVS_API dvs_status dvs_depth_estimator_create(dvs_context* context, const char* model, int32_t input_size,
                                              int32_t metric, dvs_depth_estimator** out);
/* *out = 1 for metric depth, 0 for disparity. */
DVS_API dvs_status dvs_depth_estimator_metric(const dvs_depth_estimator* estimator, int32_t* out);
/* frames: u8 [F,H,W,3] RGB; out: f32 [F,H,W], disparity (metric depth for a metric model), the same estimate as
 * `dvs depth` for the same frames. progress may be NULL. */
DVS_API dvs_status dvs_depth_estimator_estimate(dvs_depth_estimator* estimator, const uint8_t* frames, int32_t count,
                                                int32_t height, int32_t width, float* out, dvs_progress_fn progress,
                                                void* user);
/* A range of a VkBuffer of the context's device: elements from `offset` (a multiple of 4) on. */
typedef struct dvs_buffer_range {
  VkBuffer buffer; /* VK_NULL_HANDLE = not given */
  VkDeviceSize offset;
} dvs_buffer_range;
/* The same on the application's device buffers (a context made with dvs_context_create_on_host): frames u8
 * [F,H,W,3] in, disparity f32 [F,H,W] out; returns once the disparity is in `out`. Checked before any work. */
DVS_API dvs_status dvs_depth_estimator_estimate_device(dvs_depth_estimator* estimator, dvs_buffer_range frames,
                                                       int32_t count, int32_t height, int32_t width,
                                                       dvs_buffer_range out, dvs_progress_fn progress, void* user);
DVS_API dvs_status dvs_depth_estimator_destroy(dvs_depth_estimator* estimator);

/* ---- jobs: long work on a thread of its own (dvs/job.hpp) ------------------------------------------------- */

/* The common fields of dvs::RenderJob (`dvs render`). Strings are copied when the job starts; NULL = unset. Fill
 * with dvs_render_options_default first. */
typedef struct dvs_render_options {
  const char* video;       /* the input clip (required) */
  const char* depth;       /* its depth (.npz/.npy), or NULL with depth_model */
  const char* depth_model; /* a Video-Depth-Anything checkpoint: the depth is estimated from the video */
  const char* out_dir;     /* where render.mp4, mask.mp4, mask.npy, poses.json, scene.glb go (required) */
  const char* trajectory;  /* a preset name ("loop1", "pan_left:30") or a .txt/.json/.gltf/.glb file */
  const char* device;      /* as dvs_context_create */
  int32_t frames;          /* first N frames, 0 = all */
  int32_t height, width;   /* working size */
  int32_t metric_depth;    /* nonzero: depth holds metric depth, not disparity */
  int32_t hard_points;
  int32_t depth_input_size; /* depth_model's network input */
} dvs_render_options;
/* The defaults of `dvs render`: trajectory "loop1", 49 frames, 480x720, disparity, soft splat, input 518. */
DVS_API dvs_status dvs_render_options_default(dvs_render_options* out);

/* The common fields of dvs::RunOptions (`dvs run`); 0 numbers mean the preset's default where RunOptions says so.
 * Fill with dvs_pipeline_options_default first. */
typedef struct dvs_pipeline_options {
  dvs_render_options render;
  const char* model;  /* the CogVideoX-5b-I2V folder (required) */
  const char* prompt;
  const char* negative_prompt;
  const char* preset; /* "paper" or "official" */
  const char* cache_dir;
  const char* lora;
  int32_t steps, inversion_steps;
  double strength, k, delta, guidance, lora_scale;
  uint64_t seed;
  int32_t use_cache;
} dvs_pipeline_options;
/* The defaults of `dvs run` (preset "paper", k 10, guidance 6, seed 42, cache on). */
DVS_API dvs_status dvs_pipeline_options_default(dvs_pipeline_options* out);

typedef enum dvs_job_state {
  DVS_JOB_RUNNING = 0,
  DVS_JOB_SUCCEEDED = 1,
  DVS_JOB_FAILED = 2,
  DVS_JOB_CANCELLED = 3
} dvs_job_state;

/* Start `dvs render` / `dvs run` / `dvs depth` (video, model, out .npz/.npy; input_size 0 = 518; frames 0 = all)
 * on a thread of their own; *out receives the job at once. Options are checked by the work itself: a bad one
 * makes the job fail (see dvs_job_result). */
DVS_API dvs_status dvs_job_start_render(const dvs_render_options* options, dvs_job** out);
DVS_API dvs_status dvs_job_start_pipeline(const dvs_pipeline_options* options, dvs_job** out);
DVS_API dvs_status dvs_job_start_depth(const char* video, const char* model, const char* out_file, int32_t input_size,
                                       int32_t frames, dvs_job** out);
/* The job's state; never blocks. */
DVS_API dvs_status dvs_job_poll(const dvs_job* job, dvs_job_state* out);
/* The last progress event; never blocks. stage is copied into stage_buffer (stage_size bytes, *stage_needed: the
 * bytes it needs; stage_buffer may be NULL with stage_size 0); step and total may be NULL. */
DVS_API dvs_status dvs_job_progress(const dvs_job* job, char* stage_buffer, size_t stage_size, size_t* stage_needed,
                                    int32_t* step, int32_t* total);
/* Waits at most timeout_ms (negative = until the end); *finished (may be NULL) is 1 when the job has ended. */
DVS_API dvs_status dvs_job_wait(dvs_job* job, int64_t timeout_ms, int32_t* finished);
/* Asks the job to stop at its next check; dvs_job_poll says when it has (DVS_JOB_CANCELLED). */
DVS_API dvs_status dvs_job_cancel(dvs_job* job);
/* The message of a failed job ("" otherwise), copied into buffer (*needed: the bytes it needs, NUL included). */
DVS_API dvs_status dvs_job_error(const dvs_job* job, char* buffer, size_t size, size_t* needed);
/* Waits for the end and returns the work's own outcome: DVS_OK when it succeeded, else its error code with the
 * message in dvs_last_error() (DVS_ERROR_CANCELLED for a cancelled job). */
DVS_API dvs_status dvs_job_result(dvs_job* job);
/* Cancels a running job, waits for it to stop, frees it. */
DVS_API dvs_status dvs_job_destroy(dvs_job* job);

/* A whole run on a clip in memory (dvs/clip_run.hpp), on `context`: frames, depth and camera path in, the new view,
 * its mask and the sampled latent out; nothing is written but the inversion and latent caches (options->use_cache,
 * cache_dir). options as dvs_job_start_pipeline's, except that render.video, render.depth, render.depth_model and
 * render.out_dir must be NULL, render.height/width must be the frames' size and render.frames 0 or count
 * (render.device is ignored: the context is the device); each mismatch is DVS_ERROR_INVALID_ARGUMENT naming the
 * option, as is a count that is not 4k+1 or a size that is not a multiple of 8 (named before the latent's size).
 *   frames: u8 [count,height,width,3] RGB at the working size (height, width multiples of 8; count = 4k+1).
 *   depth:  f32 [count,height,width], disparity (dvs_depth_estimator_estimate's), or metric depth with
 *           options->render.metric_depth.
 *   poses:  16*count doubles, one row-major 4x4 world-to-camera transform per frame (dvs_scene_render's
 *           convention), or NULL for the path options->render.trajectory names.
 *   output: u8 [count,height,width,3], the new view. mask: f32 [count,height,width] (1 = visible in the render), or
 *           NULL. latent: f32 [Fl,C,h,w] (dvs_clip_latent_shape; latent_floats = their product, checked), or NULL.
 * Given the frames a video decode gives and the depth a depth file holds, the latent is the one `dvs run` samples. */
DVS_API dvs_status dvs_run_pipeline_clip(dvs_context* context, const dvs_pipeline_options* options,
                                         const uint8_t* frames, int32_t count, int32_t height, int32_t width,
                                         const float* depth, const double* poses, uint8_t* output, float* mask,
                                         float* latent, size_t latent_floats, dvs_progress_fn progress, void* user);
/* The same on a thread of its own; *out receives the job at once (dvs_job_poll, dvs_job_result, ...). The frames,
 * depth, output, mask and latent must stay valid until the job has finished; options and poses are copied. The job
 * holds the context until then: another thread's call on it is refused (see Threads above; a second context on the
 * same device works beside it), and dvs_context_destroy cancels the job and waits for its end. */
DVS_API dvs_status dvs_job_start_pipeline_clip(dvs_context* context, const dvs_pipeline_options* options,
                                               const uint8_t* frames, int32_t count, int32_t height, int32_t width,
                                               const float* depth, const double* poses, uint8_t* output, float* mask,
                                               float* latent, size_t latent_floats, dvs_job** out);
/* dvs_run_pipeline_clip with the clip in, and the results out to, the application's VkBuffers (dvs::run_pipeline on a
 * ClipDeviceView; a context made with dvs_context_create_on_host): frames u8 [F,H,W,3], depth f32 [F,H,W], output u8
 * [F,H,W,3] (required), mask f32 [F,H,W] and latent f32 (dvs_clip_latent_shape) optional (buffer VK_NULL_HANDLE).
 * Every range is checked before any work; returns once the results are in the buffers. */
DVS_API dvs_status dvs_run_pipeline_clip_device(dvs_context* context, const dvs_pipeline_options* options,
                                                dvs_buffer_range frames, int32_t count, int32_t height, int32_t width,
                                                dvs_buffer_range depth, const double* poses, dvs_buffer_range output,
                                                dvs_buffer_range mask, dvs_buffer_range latent,
                                                dvs_progress_fn progress, void* user);
/* The sampled latent's shape [Fl, C, h, w] for a clip of count x height x width, read from options->model's VAE
 * config (Fl = (count-1)/4+1 for CogVideoX): latent_floats = shape[0]*shape[1]*shape[2]*shape[3]. */
DVS_API dvs_status dvs_clip_latent_shape(const dvs_pipeline_options* options, int32_t count, int32_t height,
                                         int32_t width, int64_t shape[4]);

#ifdef __cplusplus
}
#endif

#endif /* DVS_H */
