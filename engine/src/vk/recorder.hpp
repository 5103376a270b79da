// Records many dispatches, inserting a barrier only where a dispatch touches a buffer range that an earlier,
// unbarriered dispatch wrote (or writes one it read). The recording can be submitted any number of times;
// only parameter buffers the caller updates change between replays.
// With profiling on, each dispatch, copy and fill is bracketed by timestamps and its GPU time goes to the Profiler
// (copies and fills under the labels kCopyLabel and kFillLabel).
//
// Bounded submissions: boundary() closes the current command buffer ("segment") and starts the next; submit()
// submits the segments one by one, each waited for, and between two of them calls the segment hook (progress,
// cancellation). No submission then holds more than the work between two boundaries: the models place one
// after every transformer block, every T5 layer and every VAE resnet/resampling step of one frame batch.
// A recording without boundaries stays one submission.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

#include "vk/context.hpp"
#include "vk/dropped_barrier.hpp"
#include "vk/memory.hpp"
#include "vk/pipeline.hpp"

namespace dvs::vk {

class Context;

// A resource for one shader binding, in binding order. Texel-buffer bindings also need the element format.
struct Binding {
  BufferView view;
  VkFormat texel_format = VK_FORMAT_UNDEFINED;
  Binding(const BufferView& v) : view(v) {}  // NOLINT: implicit on purpose, bindings read like a list of views
  Binding(const BufferView& v, VkFormat f) : view(v), texel_format(f) {}
};

class Recorder {
 public:
  static constexpr const char* kCopyLabel = "vkCmdCopyBuffer";
  static constexpr const char* kFillLabel = "vkCmdFillBuffer";

  explicit Recorder(Context& ctx);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  void begin();  // drops any previous recording
  void dispatch(const Pipeline& p, std::initializer_list<Binding> bindings, const void* push, uint32_t push_bytes,
                uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1, const std::string& label = {});
  void dispatch(const Pipeline& p, const std::vector<Binding>& bindings, const void* push, uint32_t push_bytes,
                uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1, const std::string& label = {});
  void copy(const BufferView& src, const BufferView& dst, VkDeviceSize bytes);
  // Many pieces between the same two views in one command (offsets relative to the views): one transfer
  // command instead of one per piece, which matters where each command costs tens of µs (lavapipe).
  void copy_regions(const BufferView& src, const BufferView& dst, std::span<const VkBufferCopy> regions);
  void fill_zero(const BufferView& dst);
  void barrier();  // full compute/transfer barrier, for dependencies the tracker cannot see
  // Device memory for data an op stages inside the recording (repacked convolution operands). Each `slot`
  // is one region, reused by later requests for that slot while it is large enough (the hazard tracker
  // orders the reuse); a larger request gets a new buffer and the old one stays alive, as recorded
  // commands use it. Freed when the recording is dropped (begin, destructor).
  BufferView scratch(uint32_t slot, VkDeviceSize bytes, const std::string& what);
  // Ends the current segment here (it is labelled `label`, e.g. "transformer block 3/42") and starts the next.
  // Ignored when the current segment holds no command yet. The next segment starts with a full barrier, so
  // no dependency is lost across the cut.
  void boundary(const std::string& label);
  void end();
  // Submits the segments in order, waiting for each; may be called again to replay. Between two segments it
  // calls the recorder's segment hook, else the context's. When a hook throws, nothing more is submitted, the
  // queue is idle and the exception propagates; the recording stays valid (submit replays it from the start,
  // begin drops it).
  void submit();
  void set_segment_hook(SegmentHook hook) { hook_ = std::move(hook); }  // empty: use the context's
  // Called just before segment `index` (0-based) is submitted, by submit() and by the early flush of a long
  // recording: streamed weights (models/block_stream.hpp) submit uploads there and make the segment wait for
  // one (Context::wait_before_next). Empty: none. It belongs to one recording: begin() clears it.
  void set_segment_start_hook(std::function<void(uint32_t index)> hook) { start_hook_ = std::move(hook); }
  // Submits a recording of one segment without waiting and returns its ticket (a render loop that must not block:
  // the embedded scene). The caller waits for the ticket before it submits, begins or drops the recording again.
  // GPU times (profiling) are not collected for such a submission.
  uint64_t submit_without_wait();

  Context& context() { return ctx_; }
  bool recording() const { return recording_; }
  uint32_t dispatch_count() const { return dispatches_; }
  // Barriers recorded by barrier() (hazard barriers and explicit ones; not the one opening each segment, nor one
  // DVS_DEBUG_DROP_BARRIER left out).
  uint32_t barrier_count() const { return barriers_; }
  uint32_t segment_count() const { return segments_; }  // command buffers in the recording so far
  uint64_t submission_count() const { return submissions_; }  // vkQueueSubmit calls by this recorder, ever

 private:
  struct Range {
    VkBuffer buffer;
    VkDeviceSize begin, end;
  };
  struct Access {
    Range range;
    bool writes;
  };
  // Records the barrier a command needs against the commands before it, then its own accesses. All of one
  // command's accesses go in together: a barrier found for one binding must not drop the others from the
  // record (it did until the first GPU run, 2026-11-27: an in-place residual GEMM reads Y after writing it, the
  // barrier for that read cleared Y's write, and the next op read Y without waiting — a race lavapipe, which
  // runs dispatches one after the other, never shows).
  void track(const std::vector<Access>& accesses);
  void open_segment();
  void flush_early();
  void recycle_descriptors();  // texel views destroyed, descriptor pools reset (their work must be done)
  void close_segment(const std::string& label);
  void full_barrier();
  void collect_timestamps(uint32_t pairs);
  // With profiling on and timestamps on the queue: a timestamp pair opened before a command (its first query) and
  // closed after it; else kUntimed, and time_end does nothing.
  static constexpr uint32_t kUntimed = UINT32_MAX;
  uint32_t time_begin(const std::string& label);
  void time_end(uint32_t first_query);
  VkDescriptorSet allocate_set(VkDescriptorSetLayout layout);
  void release_resources();

  Context& ctx_;
  VkCommandBuffer cmd_ = VK_NULL_HANDLE;      // the segment being recorded
  std::vector<VkCommandBuffer> cmds_;          // one per segment, kept for later recordings
  std::vector<std::string> segment_labels_;    // per closed segment
  std::vector<uint32_t> segment_query_end_;    // timestamp pairs recorded up to the end of each segment
  uint32_t segments_ = 0;
  bool segment_empty_ = true;                  // no command since the segment's opening barrier
  uint64_t submissions_ = 0;
  SegmentHook hook_;
  std::function<void(uint32_t)> start_hook_;
  bool recording_ = false, recorded_ = false;
  std::vector<VkDescriptorPool> pools_;
  size_t pool_in_use_ = 0;
  uint32_t live_sets_ = 0;          // descriptor sets allocated since the last flush
  uint32_t flushed_segments_ = 0;   // segments already submitted by flush_early()
  std::vector<VkBufferView> texel_views_;
  std::vector<Buffer> scratch_;        // every scratch buffer of the recording
  std::vector<size_t> scratch_slot_;   // slot -> index in scratch_ + 1 (0: none yet)
  std::vector<Range> reads_, writes_;  // since the last barrier
  uint32_t dispatches_ = 0, barriers_ = 0;
  uint32_t barrier_calls_ = 0;  // barrier() calls in this recording, a dropped one included
  DroppedBarrier dropped_;      // DVS_DEBUG_DROP_BARRIER, read at begin()
  VkDeviceSize texel_alignment_ = 1;

  std::vector<VkQueryPool> query_pools_;
  std::vector<std::string> query_labels_;  // one per timestamp pair
};

}  // namespace dvs::vk
