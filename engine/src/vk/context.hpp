// The Vulkan context: instance (with validation layers on request), the chosen physical device, a logical
// device with one compute queue (a compute-only family where there is one) and every optional feature dvs can use enabled, and the per-device
// services built on it (memory, pipelines, profiling). Or, embedded (issue 22), the application's instance, device
// and queue (dvs::HostDevice), of which dvs uses only what the application enabled and destroys nothing.
//
// Submissions: every vkQueueSubmit signals the context's timeline semaphore with the next value, so value n means
// "the n-th submission has finished"; that value is the submission's ticket (the application waits for it on the
// host or on its own queue).
#pragma once
#include <vulkan/vulkan.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "dvs/context.hpp"
#include "vk/device_info.hpp"
#include "vk/device_limits.hpp"

namespace dvs::vk {

class Allocator;
class PipelineCache;
class Profiler;
class Transfer;

struct ContextOptions {
  std::string device;              // index or name substring; empty: DVS_DEVICE, else the best GPU
  bool validation = false;         // also on when DVS_VALIDATION=1
  std::string pipeline_cache_file; // empty: PipelineCache::default_file in cache_dir; "-": none
  std::filesystem::path cache_dir; // the cache folder (io/cache_root.hpp; empty: $DVS_CACHE_DIR, else ~/.cache/dvs)
};

// Where a recording split by Recorder::boundary stands after one of its submissions: `done` of `total`
// segments have run; `label` names the work the last one held ("transformer block 17/42").
struct SegmentProgress {
  uint32_t done = 0, total = 0;
  std::string label;
};
// Called between two submissions of one recording (never after the last): reports progress, and may throw
// (dvs::Cancelled on Ctrl-C) to stop the recording there.
using SegmentHook = std::function<void(const SegmentProgress&)>;

// Lists every device the loader sees (creates and destroys a private instance).
std::vector<DeviceCaps> list_devices();

class Context {
 public:
  explicit Context(const ContextOptions& options = {});
  // The application's device: checked by host_device_caps (vk/host_device.hpp, throws naming what is missing).
  // `options.device` and `options.validation` do not apply (the application owns the instance and its layers).
  Context(const HostDevice& host, const ContextOptions& options);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  // The queue streamed weights are uploaded on (models/block_stream.hpp): a transfer-only family's queue where the
  // device has one (a GPU's copy engine, which runs beside the compute), else the compute queue itself.
  VkQueue transfer_queue() const { return transfer_queue_; }
  uint32_t transfer_queue_family() const { return transfer_family_; }
  bool has_transfer_queue() const { return transfer_family_ != queue_family_; }
  const DeviceCaps& caps() const { return caps_; }
  // Lowers the limits in force further than DVS_LIMITS does (min of both), or back to DVS_LIMITS alone with
  // {} (tests that force one op's split paths: tests/support/scoped_limits.hpp). The allocator's existing
  // blocks are kept; new ones follow the new alloc limit.
  void override_limits(const LimitOverrides& extra);
  bool validation_enabled() const { return validation_; }
  // Names an object in the validation layer's messages (a pipeline by its shader, a command buffer by its
  // segment), so that a message says which op it is about; does nothing without validation on dvs's own instance.
  void name_object(VkObjectType type, uint64_t handle, const std::string& name) const;
  bool owns_device() const { return owns_device_; }  // false on the application's device
  // The largest buffer range any dispatch has bound since the last reset (storage or texel binding; Recorder
  // notes every one): benchmarks print it next to maxStorageBufferRange.
  void note_binding(VkDeviceSize bytes) { largest_binding_ = std::max(largest_binding_, bytes); }
  VkDeviceSize largest_binding() const { return largest_binding_; }
  void reset_largest_binding() { largest_binding_ = 0; }
  // Which ops took a split path (their work over several bounded dispatches because one would exceed a limit
  // in force), and how often, since the last reset: tests check that forced limits really split each op.
  void note_split(const std::string& op) { ++splits_[op]; }
  const std::map<std::string, uint64_t>& splits() const { return splits_; }
  void reset_splits() { splits_.clear(); }
  // Which kernel each call of a GEMM-shaped op (linear, attention, convolution) dispatched, and for a call that
  // ran another family than the tuning asked for, why; `device`: the reason is this device's (a limit, no
  // tensor-core shape), not the call's (its options or sizes, the same on every device). Counted per call since
  // the context began: the tensor-core pass (tests/run_coopmat_pass.sh) fails a test with a device reason.
  struct KernelNote {
    std::string op, family, shader, fallback;
    bool device = false;
    auto operator<=>(const KernelNote&) const = default;
  };
  void note_kernel(const KernelNote& note) { ++kernel_notes_[note]; }
  const std::map<KernelNote, uint64_t>& kernel_notes() const { return kernel_notes_; }

  Allocator& allocator() { return *allocator_; }
  PipelineCache& pipelines() { return *pipelines_; }
  Profiler& profiler() { return *profiler_; }
  Transfer& transfer() { return *transfer_; }

  // Validation-layer messages (warnings and errors) received since the last clear.
  std::vector<std::string> validation_messages() const;
  void clear_validation_messages();
  void add_validation_message(std::string msg);

  // Submits one command buffer and waits for it (used by Transfer and Recorder); the caller keeps `cmd`.
  void submit_and_wait(VkCommandBuffer cmd);
  // Submits without waiting and returns the ticket. The context takes `cmd` (from allocate_command_buffer) and
  // frees it once the timeline has reached the ticket.
  uint64_t submit(VkCommandBuffer cmd);
  // Submits without waiting and returns the ticket; the caller keeps `cmd` and must not reset or resubmit it
  // before the ticket is reached (Recorder::submit_without_wait).
  uint64_t submit_kept(VkCommandBuffer cmd) { return queue_submit(cmd); }
  // One vkQueueSubmit of `cmd` (from a pool of transfer_queue_family()) to transfer_queue(): it waits until this
  // context's timeline reaches `after` (work on the compute queue it must follow), then signals `semaphore` (a
  // timeline semaphore of this device) with `value`. Not counted as a submission of the context's timeline.
  void submit_transfer(VkCommandBuffer cmd, uint64_t after, VkSemaphore semaphore, uint64_t value);
  uint64_t submission_count() const { return submissions_; }  // vkQueueSubmit calls so far = the last ticket
  VkSemaphore timeline() const { return timeline_; }
  uint64_t completed_value() const;  // the timeline's current value
  // Blocks until the timeline reaches `ticket` (false when timeout_ns passed first); then runs what
  // release_after queued for the tickets reached. A ticket not submitted yet is an error (it would never come).
  bool wait(uint64_t ticket, uint64_t timeout_ns = UINT64_MAX);
  // Runs `release` once the timeline has reached `ticket` (checked at every submission and wait, and before the
  // context goes): keeps what a submitted command uses, such as a Tensor's storage, alive until it has run.
  void release_after(uint64_t ticket, std::function<void()> release);
  // The next submission waits (all commands) until `semaphore`, a timeline semaphore of this device, reaches `value`.
  void wait_before_next(VkSemaphore semaphore, uint64_t value);
  // The hook every Recorder without its own calls between segments (empty: none). Set for a job's duration
  // with ScopedSegmentHook.
  const SegmentHook& segment_hook() const { return segment_hook_; }
  void set_segment_hook(SegmentHook hook) { segment_hook_ = std::move(hook); }
  VkCommandPool command_pool() const { return command_pool_; }
  VkCommandBuffer allocate_command_buffer();  // primary, from the context's pool

 private:
  void create_services(const ContextOptions& options);  // pool, timeline, allocator, transfer, pipelines, profiler
  void release();
  uint64_t queue_submit(VkCommandBuffer cmd);  // one vkQueueSubmit signalling the next timeline value
  void release_reached();                      // runs the release_after actions whose tickets were reached
  void drain_shared_queue();                   // vkQueueWaitIdle on the application's queue, under its locks

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  PFN_vkSetDebugUtilsObjectNameEXT set_object_name_ = nullptr;  // with validation only
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkQueue transfer_queue_ = VK_NULL_HANDLE;  // queue_ where the device has no transfer-only family
  uint32_t transfer_family_ = 0;
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  VkSemaphore timeline_ = VK_NULL_HANDLE;
  uint64_t submissions_ = 0;
  bool owns_device_ = true;
  std::function<void()> lock_queue_, unlock_queue_;  // the application's queue lock (may be empty)
  std::vector<std::pair<VkSemaphore, uint64_t>> waits_before_next_;
  std::vector<std::pair<uint64_t, std::function<void()>>> pending_releases_;  // ticket, action
  SegmentHook segment_hook_;
  DeviceCaps caps_;
  bool validation_ = false;
  VkDeviceSize largest_binding_ = 0;
  std::map<std::string, uint64_t> splits_;
  std::map<KernelNote, uint64_t> kernel_notes_;

  mutable std::mutex messages_mutex_;
  std::vector<std::string> messages_;

  std::unique_ptr<Allocator> allocator_;
  std::unique_ptr<Transfer> transfer_;
  std::unique_ptr<PipelineCache> pipelines_;
  std::unique_ptr<Profiler> profiler_;
};

// Installs a context's segment hook for one scope, restoring the previous one after.
class ScopedSegmentHook {
 public:
  ScopedSegmentHook(Context& ctx, SegmentHook hook) : ctx_(ctx), previous_(ctx.segment_hook()) {
    ctx_.set_segment_hook(std::move(hook));
  }
  ~ScopedSegmentHook() { ctx_.set_segment_hook(std::move(previous_)); }
  ScopedSegmentHook(const ScopedSegmentHook&) = delete;
  ScopedSegmentHook& operator=(const ScopedSegmentHook&) = delete;

 private:
  Context& ctx_;
  SegmentHook previous_;
};

}  // namespace dvs::vk
