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

/* Option structs that can grow: the first member, struct_size, is sizeof the struct as the caller's dvs.h declares
 * it, set by the *_default call that fills the struct (call it first, then set fields). Every call checks it: a
 * struct from an older dvs.h (smaller) gets the defaults for the fields it lacks; one from a newer dvs.h (larger) is
 * accepted when the fields this library does not know are zero, and refused naming struct_size otherwise; 0 or a
 * size below the first version's (a struct never filled) is DVS_ERROR_INVALID_ARGUMENT naming struct_size. Fields
 * are only ever added at the end; a struct that holds another refers to it by pointer, never by value. */

/* dvs::RenderJob (`dvs render`, and the render part of `dvs run`). Strings are copied when a call starts; NULL =
 * unset. Fill with dvs_render_options_default first. Messages name the fields "dvs_render_options.<field>". */
typedef struct dvs_render_options {
  size_t struct_size;      /* sizeof(dvs_render_options); set by dvs_render_options_default */
  const char* video;       /* the input clip (required) */
  const char* depth;       /* its depth (.npz/.npy), or NULL with depth_model */
  const char* depth_model; /* a Video-Depth-Anything checkpoint: the depth is estimated from the video */
  const char* out_dir;     /* where render.mp4, mask.mp4, mask.npy, poses.json, scene.glb go (required) */
  const char* trajectory;  /* a preset name ("loop1", "pan_left:30") or a .txt/.json/.gltf/.glb file */
  const char* device;      /* as dvs_context_create */
  int32_t frames;          /* first N frames, 0 = all */
  int32_t height, width;   /* working size */
  int32_t metric_depth;    /* nonzero: depth holds metric depth, not disparity */
  int32_t hard_points;     /* nonzero: z-buffer point splat (`--points`) */
  int32_t depth_input_size; /* depth_model's network input */
  int32_t squash;          /* nonzero: resize the video by squashing (`--resize squash`); 0: crop the centre */
  int32_t trim_depth;      /* nonzero: a depth file may hold more frames than the video uses (`--trim-depth`) */
  const char* depth_fit;   /* depth of another aspect ratio: "error" (default), "stretch" or "crop" (`--depth-fit`) */
  double fx, fy, cx, cy;   /* intrinsics in pixels of the working size (`--intrinsics`); all 0 = the default camera */
  int32_t export_glb;      /* render jobs: write scene.glb (default 1; `--no-glb` = 0) */
  int32_t save_npy;        /* render jobs: also render.npy, the render before video encoding (`--save-npy`) */
  const char* depth_cache_dir; /* render jobs: depth_model's cache, NULL = $DVS_CACHE_DIR or ~/.cache/dvs */
  int32_t depth_cache;     /* render jobs: 0 = estimate again even when cached (`--no-cache`) */
} dvs_render_options;
/* The defaults of `dvs render`: trajectory "loop1", 49 frames, 480x720, disparity, soft splat, input 518, crop,
 * depth_fit "error", the default camera, scene.glb written, depth cache on; struct_size = sizeof. */
DVS_API dvs_status dvs_render_options_default(dvs_render_options* out);

/* dvs::RunOptions (`dvs run`): every option `dvs run --help` lists but the program's own (--progress, --check,
 * --from). 0 numbers mean the preset's default where RunOptions says so (steps, inversion_steps, strength, delta);
 * a negative one is refused naming the field. Fill with dvs_pipeline_options_default first. Messages name the
 * fields "dvs_pipeline_options.<field>" (and "dvs_pipeline_options.render-><field>"). */
typedef struct dvs_pipeline_options {
  size_t struct_size;                /* sizeof(dvs_pipeline_options); set by dvs_pipeline_options_default */
  const dvs_render_options* render;  /* the render part (video, depth, trajectory, size, ...); NULL = the defaults */
  const char* model;                 /* the CogVideoX-5b-I2V folder (required) */
  const char* prompt;
  const char* negative_prompt;
  const char* preset;                /* "paper" or "official" */
  const char* cache_dir;             /* NULL = $DVS_CACHE_DIR or ~/.cache/dvs */
  const char* lora;                  /* a LoRA adapter (.safetensors) on the transformer, or NULL */
  int32_t steps, inversion_steps;    /* 0 = the preset's */
  double strength, k, delta, guidance, lora_scale; /* strength, delta: 0 = the preset's */
  uint64_t seed;
  int32_t use_cache;                 /* 0 = neither read nor write the cache (`--no-cache`) */
  int32_t dynamic_cfg;               /* the official position-wise guidance: -1 = the preset's choice, 0 off, 1 on */
  double preservation_scale;         /* its scale for fully visible latents (default 1) */
  int32_t vae_tiling;                /* nonzero: VAE encode/decode in spatial tiles (`--vae-tiling`): less memory */
  int32_t vae_tile_height, vae_tile_width; /* the tile in pixels, multiples of 8; 0 = half the VAE's sample size */
  const char* weights;               /* the transformer's and T5's block weights (`--weights`): "auto" (streamed from
                                      * host memory only where resident ones do not fit), "resident" or "stream";
                                      * the results are the same bytes either way */
} dvs_pipeline_options;
/* The defaults of `dvs run` (preset "paper", k 10, guidance 6, seed 42, cache on, dynamic_cfg -1, preservation
 * scale 1, untiled, weights "auto"); render = NULL (dvs_render_options_default's values); struct_size = sizeof. */
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
 * cache_dir). options as dvs_job_start_pipeline's, except that render->video, render->depth, render->depth_model and
 * render->out_dir must be NULL, render->height/width must be the frames' size and render->frames 0 or count
 * (render->device, squash's decode, trim_depth and depth_fit do not apply: the clip is in memory at its size; squash
 * still picks the default camera); each mismatch is DVS_ERROR_INVALID_ARGUMENT naming the option, as is a count that
 * is not 4k+1 or a size that is not a multiple of 8 (named before the latent's size).
 *   frames: u8 [count,height,width,3] RGB at the working size (height, width multiples of 8; count = 4k+1).
 *   depth:  f32 [count,height,width], disparity (dvs_depth_estimator_estimate's), or metric depth with
 *           options->render->metric_depth.
 *   poses:  16*count doubles, one row-major 4x4 world-to-camera transform per frame (dvs_scene_render's
 *           convention), or NULL for the path options->render->trajectory names.
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

/* ---- the library's own messages (dvs/logs.hpp) ------------------------------------------------------------- */

typedef enum dvs_log_level { DVS_LOG_WARNING = 1 } dvs_log_level;
/* A warning of the library (a camera path that shows nothing in some frames, a cache that cannot be written, a
 * prompt longer than the model reads, a damaged cache entry computed again, a video written as an .npy array), its
 * options named as this header's fields ("dvs_pipeline_options.prompt"). Called on the thread that has it (a job's
 * own thread for a job); the message is valid during the call only. */
typedef void (*dvs_log_fn)(dvs_log_level level, const char* message, void* user);
/* Process-wide: every later message goes to fn with user; fn NULL = the default, a line "dvs: warning: ..." on
 * stderr (in this header's names; also what a program that never calls this gets). To silence them, pass a
 * function that does nothing. */
DVS_API dvs_status dvs_set_log_callback(dvs_log_fn fn, void* user);

/* ---- camera paths (dvs/trajectory.hpp) ----------------------------------------------------------------------- */
/* Poses are 16 doubles each, row-major 4x4 world-to-camera transforms whose world is the source camera
 * (dvs_scene_render's convention; identity = the input view); `poses` holds 16*count doubles. */

/* Any trajectory `dvs run --trajectory` takes, a preset ("loop1", "pan_left:30") or a .txt/.json/.gltf/.glb file,
 * as `frames` poses into poses (pose_doubles = 16*frames, checked). radius: the orbit radius of the presets and
 * the official .txt files (dvs_scene_orbit_radius of frame 0; > 0); JSON and glTF files ignore it. */
DVS_API dvs_status dvs_trajectory_load(const char* spec, int32_t frames, double radius, double* poses,
                                       size_t pose_doubles);
/* The per-frame path through key poses (key_count keys: key_frames[i] pinned to key_poses[16*i..]; frames sorted
 * and distinct in 0..frames-1): slerp of the orientation and a straight line of the camera centre between keys,
 * each key's frame exactly its pose. poses: pose_doubles = 16*frames. */
DVS_API dvs_status dvs_trajectory_interpolate(const int32_t* key_frames, const double* key_poses, int32_t key_count,
                                              int32_t frames, double* poses, size_t pose_doubles);
/* Writes count poses as a trajectory file `dvs run --trajectory` reads: a .json (exact doubles; description may be
 * NULL) or a .glb camera animation at fps (floats; fps > 0). */
DVS_API dvs_status dvs_trajectory_write_json(const char* path, const double* poses, int32_t count,
                                             const char* description);
DVS_API dvs_status dvs_trajectory_write_glb(const char* path, const double* poses, int32_t count, double fps);

/* ---- checks before any work (dvs/preflight.hpp) ------------------------------------------------------------- */
/* Everything knowable about a run (or a render) in milliseconds, nothing run or written: the options, the video,
 * depth and output folder, the model's configs and weight headers, the LoRA, the VAE tiling and the device's memory
 * as the memory plan sees it. DVS_OK means the check itself ran; *problems (may be NULL) is how many problems it
 * found (0 = the run would start). report: the problems, one per line as "problem: <what is wrong and the fix>",
 * then the notes as "note: <fact>" (a warning among them as "note: warning: ..."), copied into report (size bytes,
 * NUL-terminated; NULL with size 0 to ask only); *needed (may be NULL) = the bytes the whole report needs. */
DVS_API dvs_status dvs_preflight_pipeline(const dvs_pipeline_options* options, int32_t* problems, char* report,
                                          size_t size, size_t* needed);
DVS_API dvs_status dvs_preflight_render(const dvs_render_options* options, int32_t* problems, char* report,
                                        size_t size, size_t* needed);

/* ---- the memory plan (dvs/plan.hpp, `dvs plan`) ------------------------------------------------------------- */
/* Planned from the model's config.json files alone (no weights read, no device opened unless `device` is given). */
typedef struct dvs_plan_request {
  size_t struct_size;       /* sizeof(dvs_plan_request); set by dvs_plan_request_default */
  const char* model;        /* a CogVideoX folder, or the built-in "cogvideox-5b-i2v" (required) */
  int32_t frames, height, width; /* the clip (4k+1 frames; default 49 x 480 x 720) */
  uint64_t budget;          /* device memory available in bytes; 0 = the limits' memory (if any) */
  uint64_t alignment;       /* the allocator's alignment (default 256) */
  const char* device;       /* plan against this device's limits and memory (index or name part), or NULL */
  const char* limits;       /* or a typical device: "lavapipe", "nvidia", "amd", "intel", "apple", "min"; or NULL */
  const char* depth_model;  /* include `--depth-model`'s estimate: a checkpoint or "vits"/"vitb"/"vitl"; or NULL */
  int32_t depth_input_size; /* its network input (default 518) */
  int32_t depth_frame_height, depth_frame_width; /* the video's frames; 0 = the clip size */
  const char* weights;      /* the block weights as `dvs plan --weights`: "auto" (default), "resident" or "stream" */
  double upload_bytes_per_second; /* host -> device rate for the upload times (`--upload-rate`); 0 = the limits' */
} dvs_plan_request;
DVS_API dvs_status dvs_plan_request_default(dvs_plan_request* out);

typedef struct dvs_plan_result {
  size_t struct_size;       /* set by the caller to sizeof(dvs_plan_result): the fields written are those it holds */
  int32_t checked;          /* 1 when a budget, device or limits were given */
  int32_t runs;             /* 1 when some setting runs within them (always 1 when not checked) */
  uint64_t weights_bytes;   /* every weight, resident */
  uint64_t run_peak_bytes;  /* the run's peak, untiled */
} dvs_plan_result;
/* Plans the run: *result (may be NULL), and the plan as `dvs plan` prints it (json = 0) or as its JSON object
 * (json = 1, `dvs plan --json`: every stage, every tiling, the tile that fits) copied into text (size bytes;
 * NULL with size 0 to ask only); *needed (may be NULL) = the bytes the whole text needs. */
DVS_API dvs_status dvs_plan_run_memory(const dvs_plan_request* request, dvs_plan_result* result, int32_t json,
                                       char* text, size_t size, size_t* needed);

#ifdef __cplusplus
}
#endif

#endif /* DVS_H */
