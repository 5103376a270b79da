#include "vk/recorder.hpp"

#include <algorithm>
#include <vector>

#include "vk/check.hpp"
#include "vk/context.hpp"
#include "vk/device_limits.hpp"
#include "vk/profiler.hpp"

namespace dvs::vk {
namespace {
constexpr uint32_t kSetsPerPool = 512;
// Descriptor sets one recording keeps alive at most. Mesa 25's lavapipe maps memory for every set, so a recording
// of ~90,000 dispatches (the VAE decode split under 64 KiB bindings) ran into the kernel's 65,530 memory maps and
// crashed inside vkAllocateDescriptorSets; past this many sets the segments closed so far are submitted early.
constexpr uint32_t kMaxLiveSets = 8192;
constexpr uint32_t kQueriesPerPool = 1024;  // 512 timestamp pairs
constexpr const char* kFlushLabel = "descriptor flush";  // segments cut by flush_early(), not by boundary()

}  // namespace

Recorder::Recorder(Context& ctx) : ctx_(ctx) {
  cmds_.push_back(ctx.allocate_command_buffer());
  cmd_ = cmds_[0];
  VkPhysicalDeviceProperties p{};
  vkGetPhysicalDeviceProperties(ctx.physical_device(), &p);
  texel_alignment_ = p.limits.minTexelBufferOffsetAlignment;
}

Recorder::~Recorder() {
  release_resources();
  VkDevice dev = ctx_.device();
  for (VkDescriptorPool p : pools_) vkDestroyDescriptorPool(dev, p, nullptr);
  for (VkQueryPool q : query_pools_) vkDestroyQueryPool(dev, q, nullptr);
  if (!cmds_.empty()) vkFreeCommandBuffers(dev, ctx_.command_pool(), uint32_t(cmds_.size()), cmds_.data());
}

void Recorder::recycle_descriptors() {
  VkDevice dev = ctx_.device();
  for (VkBufferView v : texel_views_) vkDestroyBufferView(dev, v, nullptr);
  texel_views_.clear();
  for (VkDescriptorPool p : pools_) vkResetDescriptorPool(dev, p, 0);
  pool_in_use_ = 0;
  live_sets_ = 0;
}

void Recorder::release_resources() {
  recycle_descriptors();
  scratch_.clear();
  scratch_slot_.clear();
}

BufferView Recorder::scratch(uint32_t slot, VkDeviceSize bytes, const std::string& what) {
  if (slot >= scratch_slot_.size()) scratch_slot_.resize(slot + 1, 0);
  size_t& idx = scratch_slot_[slot];
  if (idx == 0 || scratch_[idx - 1].view().size < bytes) {
    scratch_.push_back(ctx_.allocator().allocate(std::max<VkDeviceSize>(bytes, 16), MemoryUse::device, what));
    idx = scratch_.size();
  }
  BufferView v = scratch_[idx - 1].view();
  v.size = std::max<VkDeviceSize>(bytes, 16);
  return v;
}

void Recorder::begin() {
  if (recording_) throw Error("internal: Recorder::begin while recording");
  release_resources();
  start_hook_ = {};
  reads_.clear();
  writes_.clear();
  query_labels_.clear();
  dispatches_ = barriers_ = barrier_calls_ = 0;
  dropped_ = dropped_barrier_from_env();
  segments_ = 0;
  flushed_segments_ = 0;
  segment_labels_.clear();
  segment_query_end_.clear();
  recorded_ = false;
  open_segment();
  recording_ = true;
}

void Recorder::open_segment() {
  if (segments_ == cmds_.size()) cmds_.push_back(ctx_.allocate_command_buffer());
  cmd_ = cmds_[segments_++];
  VK_CHECK(vkResetCommandBuffer(cmd_, 0));
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  VK_CHECK(vkBeginCommandBuffer(cmd_, &bi));
  // Named for the validation layer's messages while it is recorded; close_segment adds its label.
  ctx_.name_object(VK_OBJECT_TYPE_COMMAND_BUFFER, uint64_t(cmd_), "segment " + std::to_string(segments_) + " (recording)");
  // Host writes to parameter buffers, earlier submissions and the earlier segments of this recording must be
  // visible to this one. A pipeline barrier's first scope covers every command earlier in submission order,
  // other command buffers included, so this one barrier orders the whole previous segment before this one
  // (the tracker's ranges are cleared: nothing before it is pending).
  if (dropped_.drops_segment(segments_)) {
    reads_.clear();  // DVS_DEBUG_DROP_BARRIER: left out, tracked as if recorded
    writes_.clear();
  } else {
    full_barrier();
  }
  segment_empty_ = true;
}

void Recorder::close_segment(const std::string& label) {
  // Results must be visible to the host (a segment hook may read them) and to later submissions.
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &mb, 0, nullptr, 0, nullptr);
  VK_CHECK(vkEndCommandBuffer(cmd_));
  ctx_.name_object(VK_OBJECT_TYPE_COMMAND_BUFFER, uint64_t(cmd_), "segment " + std::to_string(segments_) + " (" + label + ")");
  segment_labels_.push_back(label);
  segment_query_end_.push_back(uint32_t(query_labels_.size()));
}

// Submits (and waits for) every segment closed so far, then recycles their descriptor sets and texel views; the
// recording goes on in a new segment. Scratch buffers and timestamp queries stay (later segments and submit()
// use them). Progress hooks run only in submit(): an early flush is an implementation detail of long recordings.
void Recorder::flush_early() {
  close_segment(kFlushLabel);
  const SegmentHook hook = hook_ ? hook_ : ctx_.segment_hook();
  for (uint32_t i = flushed_segments_; i < segments_; ++i) {
    if (start_hook_) start_hook_(i);
    ctx_.submit_and_wait(cmds_[i]);
    ++submissions_;
    // The recording's own boundaries are reported as submit() reports them; the flush's cut is not one.
    if (hook && segment_labels_[i] != kFlushLabel) hook(SegmentProgress{i + 1, segments_, segment_labels_[i]});
  }
  // Flushed segments are never submitted again (submit() starts after them): their commands go now. A driver
  // that keeps recorded commands in host memory (lavapipe) otherwise holds every command of the recording, and
  // a recording of millions of dispatches (an untiled 480x720 VAE decode under the minimum texel-view limit) grew
  // to 14 GB of host memory beside its 7.6 GiB of tensors.
  for (uint32_t i = flushed_segments_; i < segments_; ++i)
    VK_CHECK(vkResetCommandBuffer(cmds_[i], VK_COMMAND_BUFFER_RESET_RELEASE_RESOURCES_BIT));
  flushed_segments_ = segments_;
  recycle_descriptors();
  open_segment();
}

void Recorder::boundary(const std::string& label) {
  if (!recording_) throw Error("internal: Recorder::boundary outside begin()/end()");
  if (segment_empty_) return;  // no empty submissions
  close_segment(label);
  open_segment();
}

VkDescriptorSet Recorder::allocate_set(VkDescriptorSetLayout layout) {
  VkDevice dev = ctx_.device();
  while (true) {
    if (pool_in_use_ == pools_.size()) {
      VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kSetsPerPool * 8},
                                      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, kSetsPerPool},
                                      {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kSetsPerPool * 4},
                                      {VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER, kSetsPerPool}};
      VkDescriptorPoolCreateInfo pci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
      pci.maxSets = kSetsPerPool;
      pci.poolSizeCount = 4;
      pci.pPoolSizes = sizes;
      VkDescriptorPool pool;
      VK_CHECK(vkCreateDescriptorPool(dev, &pci, nullptr, &pool));
      pools_.push_back(pool);
    }
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = pools_[pool_in_use_];
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &layout;
    VkDescriptorSet set;
    VkResult r = vkAllocateDescriptorSets(dev, &ai, &set);
    if (r == VK_SUCCESS) return set;
    if (r != VK_ERROR_OUT_OF_POOL_MEMORY && r != VK_ERROR_FRAGMENTED_POOL) VK_CHECK(r);
    pool_in_use_++;
  }
}

void Recorder::track(const std::vector<Access>& accesses) {
  auto overlaps = [](const std::vector<Range>& v, const Range& r) {
    for (const Range& o : v)
      if (o.buffer == r.buffer && o.begin < r.end && r.begin < o.end) return true;
    return false;
  };
  bool hazard = false;
  for (const Access& a : accesses)
    hazard = hazard || overlaps(writes_, a.range) || (a.writes && overlaps(reads_, a.range));
  if (hazard) barrier();
  for (const Access& a : accesses) (a.writes ? writes_ : reads_).push_back(a.range);
}

void Recorder::barrier() {
  if (dropped_.drops_hazard(++barrier_calls_)) {
    reads_.clear();  // DVS_DEBUG_DROP_BARRIER: left out, tracked as if recorded
    writes_.clear();
    return;
  }
  full_barrier();
  barriers_++;
}

void Recorder::full_barrier() {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                     VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_UNIFORM_READ_BIT;
  vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &mb, 0, nullptr, 0,
                       nullptr);
  reads_.clear();
  writes_.clear();
}

void Recorder::dispatch(const Pipeline& p, std::initializer_list<Binding> bindings, const void* push,
                        uint32_t push_bytes, uint32_t gx, uint32_t gy, uint32_t gz, const std::string& label) {
  dispatch(p, std::vector<Binding>(bindings), push, push_bytes, gx, gy, gz, label);
}

void Recorder::dispatch(const Pipeline& p, const std::vector<Binding>& bindings, const void* push,
                        uint32_t push_bytes, uint32_t gx, uint32_t gy, uint32_t gz, const std::string& label) {
  if (!recording_) throw Error("internal: dispatch outside begin()/end()");
  const auto& decl = p.iface.bindings;
  if (bindings.size() != decl.size())
    throw Error("internal: shader " + p.name + " declares " + std::to_string(decl.size()) + " bindings, " +
                std::to_string(bindings.size()) + " given");
  const DeviceCaps& caps = ctx_.caps();
  if (gx == 0 || gy == 0 || gz == 0) return;  // nothing to do (empty tensor)
  // The limits in force (the device's, or lower under DVS_LIMITS): an op that meets a large tensor must split
  // its work so that no dispatch exceeds them; getting here means one did not (a bug in that op).
  if (gx > caps.max_workgroup_count[0] || gy > caps.max_workgroup_count[1] || gz > caps.max_workgroup_count[2])
    throw Error("internal: shader " + p.name + " dispatch of " + std::to_string(gx) + "x" + std::to_string(gy) + "x" +
                std::to_string(gz) + " groups exceeds maxComputeWorkGroupCount " +
                std::to_string(caps.max_workgroup_count[0]) + "x" + std::to_string(caps.max_workgroup_count[1]) + "x" +
                std::to_string(caps.max_workgroup_count[2]) + (caps.forced_limits.groups ? " (DVS_LIMITS)" : ""));
  if (push_bytes > 128 || push_bytes % 4) throw Error("internal: push constants must be ≤ 128 bytes, multiple of 4");

  if (live_sets_ >= kMaxLiveSets) flush_early();
  VkDescriptorSet set = allocate_set(p.set_layout);
  ++live_sets_;
  std::vector<VkWriteDescriptorSet> writes(decl.size());
  std::vector<VkDescriptorBufferInfo> infos(decl.size());
  std::vector<VkBufferView> views(decl.size());
  std::vector<Access> accesses;
  accesses.reserve(decl.size());
  for (size_t i = 0; i < decl.size(); ++i) {
    const BufferView& v = bindings[i].view;
    if (!v.valid()) throw Error("internal: shader " + p.name + " binding " + std::to_string(i) + " has no buffer");
    const bool texel = decl[i].kind == BindingKind::uniform_texel_buffer || decl[i].kind == BindingKind::storage_texel_buffer;
    const VkDeviceSize align = texel ? texel_alignment_ : caps.min_storage_buffer_offset_alignment;
    if (texel) {
      const uint32_t tb = texel_format_bytes(bindings[i].texel_format);
      if (tb && v.size / tb > caps.max_texel_buffer_elements)
        throw Error("internal: shader " + p.name + " binding " + std::to_string(i) + " is a texel view of " +
                    std::to_string(v.size / tb) + " texels, over maxTexelBufferElements " +
                    std::to_string(caps.max_texel_buffer_elements) + (caps.forced_limits.texels ? " (DVS_LIMITS)" : ""));
    } else if (v.size > caps.max_storage_buffer_range) {
      throw Error("internal: shader " + p.name + " binding " + std::to_string(i) + " covers " + format_bytes(v.size) +
                  " (" + std::to_string(v.size) + " B), over maxStorageBufferRange " +
                  format_bytes(caps.max_storage_buffer_range) + (caps.forced_limits.binding ? " (DVS_LIMITS)" : ""));
    }
    ctx_.note_binding(v.size);
    if (align && v.offset % align)
      throw Error("internal: shader " + p.name + " binding " + std::to_string(i) + " starts at offset " +
                  std::to_string(v.offset) + ", not a multiple of the device's " + std::to_string(align) +
                  "-byte binding alignment (bind the whole tensor and pass an element offset)");
    VkWriteDescriptorSet& w = writes[i];
    w = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = set;
    w.dstBinding = decl[i].binding;
    w.descriptorCount = 1;
    w.descriptorType = descriptor_type(decl[i].kind);
    if (decl[i].kind == BindingKind::uniform_texel_buffer || decl[i].kind == BindingKind::storage_texel_buffer) {
      if (bindings[i].texel_format == VK_FORMAT_UNDEFINED)
        throw Error("internal: shader " + p.name + " binding " + std::to_string(i) + " is a texel buffer: give a format");
      VkBufferViewCreateInfo bv{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
      bv.buffer = v.buffer;
      bv.format = bindings[i].texel_format;
      bv.offset = v.offset;
      bv.range = v.size;
      VK_CHECK(vkCreateBufferView(ctx_.device(), &bv, nullptr, &views[i]));
      texel_views_.push_back(views[i]);
      w.pTexelBufferView = &views[i];
    } else {
      infos[i] = {v.buffer, v.offset, v.size};
      w.pBufferInfo = &infos[i];
    }
    accesses.push_back({{v.buffer, v.offset, v.offset + v.size}, !decl[i].read_only});
  }
  track(accesses);
  vkUpdateDescriptorSets(ctx_.device(), uint32_t(writes.size()), writes.data(), 0, nullptr);

  const uint32_t q = time_begin(label.empty() ? p.name : label);
  vkCmdBindPipeline(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, p.pipeline);
  vkCmdBindDescriptorSets(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, p.layout, 0, 1, &set, 0, nullptr);
  if (push_bytes) vkCmdPushConstants(cmd_, p.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes, push);
  vkCmdDispatch(cmd_, gx, gy, gz);
  segment_empty_ = false;
  time_end(q);
  dispatches_++;
}

uint32_t Recorder::time_begin(const std::string& label) {
  if (!ctx_.profiler().enabled() || !ctx_.caps().timestamps) return kUntimed;
  const uint32_t q = uint32_t(query_labels_.size()) * 2;
  if (q / kQueriesPerPool >= query_pools_.size()) {
    VkQueryPoolCreateInfo qci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qci.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qci.queryCount = kQueriesPerPool;
    VkQueryPool pool;
    VK_CHECK(vkCreateQueryPool(ctx_.device(), &qci, nullptr, &pool));
    query_pools_.push_back(pool);
  }
  if (q % kQueriesPerPool == 0) vkCmdResetQueryPool(cmd_, query_pools_[q / kQueriesPerPool], 0, kQueriesPerPool);
  vkCmdWriteTimestamp(cmd_, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, query_pools_[q / kQueriesPerPool], q % kQueriesPerPool);
  query_labels_.push_back(label);
  return q;
}

void Recorder::time_end(uint32_t q) {
  if (q == kUntimed) return;
  vkCmdWriteTimestamp(cmd_, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, query_pools_[q / kQueriesPerPool], q % kQueriesPerPool + 1);
}

void Recorder::copy(const BufferView& src, const BufferView& dst, VkDeviceSize bytes) {
  if (!recording_) throw Error("internal: copy outside begin()/end()");
  if (bytes > src.size || bytes > dst.size) throw Error("internal: recorded copy larger than its buffers");
  track({{{src.buffer, src.offset, src.offset + bytes}, false}, {{dst.buffer, dst.offset, dst.offset + bytes}, true}});
  VkBufferCopy region{src.offset, dst.offset, bytes};
  const uint32_t q = time_begin(kCopyLabel);
  vkCmdCopyBuffer(cmd_, src.buffer, dst.buffer, 1, &region);
  time_end(q);
  segment_empty_ = false;
}

void Recorder::copy_regions(const BufferView& src, const BufferView& dst, std::span<const VkBufferCopy> regions) {
  if (!recording_) throw Error("internal: copy outside begin()/end()");
  if (regions.empty()) return;
  std::vector<VkBufferCopy> absolute(regions.begin(), regions.end());
  for (VkBufferCopy& r : absolute) {
    if (r.srcOffset + r.size > src.size || r.dstOffset + r.size > dst.size)
      throw Error("internal: recorded copy region outside its buffers");
    r.srcOffset += src.offset;
    r.dstOffset += dst.offset;
  }
  track({{{src.buffer, src.offset, src.offset + src.size}, false}, {{dst.buffer, dst.offset, dst.offset + dst.size}, true}});
  const uint32_t q = time_begin(kCopyLabel);
  vkCmdCopyBuffer(cmd_, src.buffer, dst.buffer, uint32_t(absolute.size()), absolute.data());
  time_end(q);
  segment_empty_ = false;
}

void Recorder::fill_zero(const BufferView& dst) {
  if (!recording_) throw Error("internal: fill outside begin()/end()");
  track({{{dst.buffer, dst.offset, dst.offset + dst.size}, true}});
  const uint32_t q = time_begin(kFillLabel);
  vkCmdFillBuffer(cmd_, dst.buffer, dst.offset, (dst.size + 3) / 4 * 4, 0);
  time_end(q);
  segment_empty_ = false;
}

void Recorder::end() {
  if (!recording_) throw Error("internal: Recorder::end without begin");
  if (segment_empty_ && segments_ > 1) {
    // A boundary just before end(): the opened segment holds only its barrier; drop it (the previous one
    // already ends with the host-visibility barrier).
    VK_CHECK(vkEndCommandBuffer(cmd_));
    --segments_;
  } else {
    close_segment("end");
  }
  recording_ = false;
  recorded_ = true;
}

void Recorder::submit() {
  if (recording_) end();
  if (!recorded_) throw Error("internal: Recorder::submit with nothing recorded");
  const SegmentHook hook = hook_ ? hook_ : ctx_.segment_hook();
  for (uint32_t i = flushed_segments_; i < segments_; ++i) {
    if (start_hook_) start_hook_(i);
    ctx_.submit_and_wait(cmds_[i]);
    ++submissions_;
    if (i + 1 == segments_ || !hook || segment_labels_[i] == kFlushLabel) continue;
    try {
      hook(SegmentProgress{i + 1, segments_, segment_labels_[i]});
    } catch (...) {
      // Stopped between segments: the queue is idle (each submission was waited for); keep the GPU times of
      // what ran.
      collect_timestamps(segment_query_end_[i]);
      throw;
    }
  }
  collect_timestamps(uint32_t(query_labels_.size()));
}

uint64_t Recorder::submit_without_wait() {
  if (recording_) end();
  if (!recorded_ || segments_ != 1 || flushed_segments_ != 0)
    throw Error("internal: Recorder::submit_without_wait needs a recording of exactly one segment");
  ++submissions_;
  return ctx_.submit_kept(cmds_[0]);
}

void Recorder::collect_timestamps(uint32_t pairs) {
  if (pairs == 0) return;
  const uint32_t total = pairs * 2;
  std::vector<uint64_t> ts(total);
  for (uint32_t first = 0; first < total; first += kQueriesPerPool) {
    uint32_t n = std::min(kQueriesPerPool, total - first);
    VK_CHECK(vkGetQueryPoolResults(ctx_.device(), query_pools_[first / kQueriesPerPool], 0, n, n * 8, &ts[first], 8,
                                   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
  }
  const double period = ctx_.caps().timestamp_period_ns;
  for (uint32_t i = 0; i < pairs; ++i) ctx_.profiler().add(query_labels_[i], double(ts[2 * i + 1] - ts[2 * i]) * period);
}

}  // namespace dvs::vk
