#include "models/block_stream.hpp"

#include <algorithm>

#include "dvs/error.hpp"
#include "models/call_memory.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"

namespace dvs::models {

BlockStream::BlockStream(vk::Context& ctx, ComponentWeights& weights, int64_t blocks,
                         const std::function<std::vector<std::string>(int64_t)>& names, int slots, std::string what)
    : ctx_(ctx), what_(std::move(what)), uploads_(ctx) {
  if (slots < 1) throw Error("internal: BlockStream needs at least 1 slot, got " + std::to_string(slots));
  if (blocks < 1) throw Error("internal: BlockStream of no blocks (" + what_ + ")");
  slots = int(std::min<int64_t>(slots, blocks));  // no more slots than blocks
  vk::Allocator& alloc = ctx.allocator();
  const uint64_t align = alloc.alignment();
  layout_.resize(size_t(blocks));
  bytes_.assign(size_t(blocks), 0);
  for (int64_t j = 0; j < blocks; ++j) {
    uint64_t& packed = bytes_[size_t(j)];
    for (const std::string& name : names(j)) {
      const ComponentWeights::Info info = weights.info(name);
      layout_[size_t(j)][name] = Entry{packed, info.shape, info.dtype};
      packed += align_up(std::max<uint64_t>(info.bytes, 1), align);
    }
    if (packed > alloc.max_allocation())
      throw Error("Streaming " + what_ + ": block " + std::to_string(j) + " holds " + vk::format_bytes(packed) +
                  " of weights, more than one allocation on this device (maxMemoryAllocationSize " +
                  vk::format_bytes(alloc.max_allocation()) + "); use --weights resident");
    slot_bytes_ = std::max(slot_bytes_, packed);
  }
  // The host copy, block by block (each weight leaves the device, if it was there, once it is copied).
  host_.reserve(size_t(blocks));
  for (int64_t j = 0; j < blocks; ++j) {
    host_.push_back(alloc.allocate(bytes_[size_t(j)], vk::MemoryUse::pinned,
                                   what_ + " block " + std::to_string(j) + " (host copy)"));
    uint8_t* base = host_.back().mapped();
    if (!base) throw Error("internal: pinned host memory is not mapped (" + what_ + ")");
    for (const auto& [name, e] : layout_[size_t(j)]) {
      weights.copy_to_host(name, base + e.offset);
      weights.release(name);
    }
  }
  for (int k = 0; k < slots; ++k)  // after the host copies: their device copies are gone by now
    slots_.push_back(alloc.allocate(slot_bytes_, vk::MemoryUse::device_shared, what_ + " slot " + std::to_string(k)));
}

BlockStream::~BlockStream() = default;  // uploads_ (declared after the buffers) waits for its uploads first

uint64_t BlockStream::block_bytes(int64_t block) const { return bytes_.at(size_t(block)); }

uint64_t BlockStream::host_bytes() const {
  uint64_t n = 0;
  for (const uint64_t b : bytes_) n += b;
  return n;
}

bool BlockStream::has(int64_t block, const std::string& name) const {
  return block >= 0 && block < blocks() && layout_[size_t(block)].count(name) != 0;
}

Tensor BlockStream::get(int64_t block, const std::string& name) const {
  if (!has(block, name)) throw Error("internal: " + what_ + ": block " + std::to_string(block) + " streams no '" + name + "'");
  const Entry& e = layout_[size_t(block)].at(name);
  const uint64_t bytes = uint64_t(shape_numel(e.shape)) * dtype_size(e.dtype);
  return Tensor::on(slots_[size_t(block) % slots_.size()].view().sub(e.offset, bytes), e.shape, e.dtype);
}

void BlockStream::begin_call(vk::Recorder& rec) {
  uploads_.wait_all();  // a call stopped early (Ctrl-C) may have left uploads running into the slots
  first_segment_.assign(size_t(blocks()), UINT32_MAX);
  upload_value_.assign(size_t(blocks()), 0);
  started_ = false;
  events_.clear();
  rec.set_segment_start_hook([this](uint32_t segment) { on_segment(segment); });
}

void BlockStream::mark_block(vk::Recorder& rec, int64_t block) {
  if (block < 0 || block >= blocks() || first_segment_.size() != size_t(blocks()))
    throw Error("internal: " + what_ + ": mark_block(" + std::to_string(block) + ") outside a call begun with begin_call");
  first_segment_[size_t(block)] = rec.segment_count() - 1;
}

void BlockStream::upload(int64_t block, uint64_t after_compute) {
  const uint32_t slot = uint32_t(size_t(block) % slots_.size());
  const uint64_t value = uploads_.upload(host_[size_t(block)].view(), slots_[slot].view(), bytes_[size_t(block)], after_compute);
  upload_value_[size_t(block)] = value;
  events_.push_back({StreamEvent::Kind::upload, block, slot, after_compute, value, ctx_.submission_count()});
}

void BlockStream::on_segment(uint32_t segment) {
  const int64_t n = blocks(), k = int64_t(slots_.size());
  // Everything submitted so far has run or will run before what waits on it: the slots are free at a call's start.
  if (!started_) {
    started_ = true;
    for (int64_t j = 0; j < std::min(n, k); ++j) upload(j, ctx_.submission_count());
  }
  for (int64_t j = 0; j < n; ++j) {
    if (first_segment_[size_t(j)] != segment) continue;
    // Block j − 1 was the last to read slot (j + k − 1) % k: its segments are the compute submitted so far.
    const int64_t next = j + k - 1;
    if (j >= 1 && next < n && upload_value_[size_t(next)] == 0) upload(next, ctx_.submission_count());
    if (upload_value_[size_t(j)] == 0)
      throw Error("internal: " + what_ + ": block " + std::to_string(j) + " starts before its upload was scheduled");
    ctx_.wait_before_next(uploads_.timeline(), upload_value_[size_t(j)]);
    events_.push_back({StreamEvent::Kind::compute, j, uint32_t(size_t(j) % slots_.size()), upload_value_[size_t(j)],
                       ctx_.submission_count() + 1, ctx_.submission_count()});
  }
}

}  // namespace dvs::models
