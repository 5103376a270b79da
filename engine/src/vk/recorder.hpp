// Records many dispatches into one command buffer, inserting a barrier only where a dispatch touches a
// buffer range that an earlier, unbarriered dispatch wrote (or writes one it read). The recording can be
// submitted any number of times; only parameter buffers the caller updates change between replays.
// With profiling on, each dispatch is bracketed by timestamps and its GPU time goes to the Profiler.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

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
  void end();
  void submit();   // submit and wait; may be called again to replay

  Context& context() { return ctx_; }
  bool recording() const { return recording_; }
  uint32_t dispatch_count() const { return dispatches_; }
  uint32_t barrier_count() const { return barriers_; }

 private:
  struct Range {
    VkBuffer buffer;
    VkDeviceSize begin, end;
  };
  void track(const Range& r, bool writes);
  VkDescriptorSet allocate_set(VkDescriptorSetLayout layout);
  void release_resources();

  Context& ctx_;
  VkCommandBuffer cmd_ = VK_NULL_HANDLE;
  bool recording_ = false, recorded_ = false;
  std::vector<VkDescriptorPool> pools_;
  size_t pool_in_use_ = 0;
  std::vector<VkBufferView> texel_views_;
  std::vector<Buffer> scratch_;        // every scratch buffer of the recording
  std::vector<size_t> scratch_slot_;   // slot -> index in scratch_ + 1 (0: none yet)
  std::vector<Range> reads_, writes_;  // since the last barrier
  uint32_t dispatches_ = 0, barriers_ = 0;
  VkDeviceSize texel_alignment_ = 1;

  std::vector<VkQueryPool> query_pools_;
  std::vector<std::string> query_labels_;  // one per timestamp pair
};

}  // namespace dvs::vk
