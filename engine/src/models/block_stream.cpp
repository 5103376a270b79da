#include "models/block_stream.hpp"

#include <algorithm>

#include "dvs/error.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"
#include "vk/timestamp_queries.hpp"

namespace dvs::models {

BlockStream::BlockStream(vk::Context& ctx, ComponentWeights& weights, int64_t blocks,
                         const std::function<std::vector<std::string>(int64_t)>& names, int slots, std::string what)
    : ctx_(ctx), what_(std::move(what)), uploads_(ctx) {
  if (slots < 1) throw Error("internal: BlockStream needs at least 1 slot, got " + std::to_string(slots));
  if (blocks < 1) throw Error("internal: BlockStream of no blocks (" + what_ + ")");
  slots = int(std::min<int64_t>(slots, blocks));  // no more slots than blocks
  vk::Allocator& alloc = ctx.allocator();
  // Each tensor is one allocation, as when resident (the allocator refuses a larger one, naming it); a block is
  // packed into pieces of at most one allocation.
  const VkDeviceSize piece_limit = vk::ArenaPacking::block_limit(alloc.max_allocation(), alloc.alignment());
  layout_.resize(size_t(blocks));
  pieces_.resize(size_t(blocks));
  std::vector<uint64_t> slot_pieces;  // the largest of each piece over the blocks
  for (int64_t j = 0; j < blocks; ++j) {
    vk::ArenaPacking packing(alloc.alignment(), {}, piece_limit);
    for (const std::string& name : names(j)) {
      const ComponentWeights::Info info = weights.info(name);
      if (packing.aligned(info.bytes) > piece_limit)
        throw Error("Streaming " + what_ + ": weight '" + name + "' (" + vk::format_bytes(info.bytes) +
                    ") is larger than one allocation on this device (maxMemoryAllocationSize " +
                    vk::format_bytes(alloc.max_allocation()) + ")");
      const vk::ArenaPacking::Place p = packing.place(info.bytes);
      layout_[size_t(j)][name] = Entry{p.block, p.offset, info.shape, info.dtype};
    }
    pieces_[size_t(j)] = packing.filled().blocks;
    if (slot_pieces.size() < pieces_[size_t(j)].size()) slot_pieces.resize(pieces_[size_t(j)].size(), 0);
    for (size_t k = 0; k < pieces_[size_t(j)].size(); ++k) slot_pieces[k] = std::max(slot_pieces[k], pieces_[size_t(j)][k]);
  }
  // The host copy, block by block (each weight leaves the device, if it was there, once it is copied).
  host_.resize(size_t(blocks));
  for (int64_t j = 0; j < blocks; ++j) {
    for (size_t k = 0; k < pieces_[size_t(j)].size(); ++k) {
      host_[size_t(j)].push_back(alloc.allocate(pieces_[size_t(j)][k], vk::MemoryUse::pinned,
                                                what_ + " block " + std::to_string(j) + " (host copy)"));
      if (!host_[size_t(j)].back().mapped()) throw Error("internal: pinned host memory is not mapped (" + what_ + ")");
    }
    for (const auto& [name, e] : layout_[size_t(j)]) {
      weights.copy_to_host(name, host_[size_t(j)][e.piece].mapped() + e.offset);
      weights.release(name);
    }
  }
  slots_.resize(size_t(slots));
  for (int s = 0; s < slots; ++s)  // after the host copies: their device copies are gone by now
    for (const uint64_t bytes : slot_pieces)
      slots_[size_t(s)].push_back(alloc.allocate(bytes, vk::MemoryUse::device_shared, what_ + " slot " + std::to_string(s)));
}

uint64_t BlockStream::slot_bytes() const {
  uint64_t n = 0;
  for (const vk::Buffer& b : slots_.front()) n += b.size();
  return n;
}

BlockStream::~BlockStream() = default;  // stamps_ and uploads_ (after the buffers) wait for their work first

uint64_t BlockStream::block_bytes(int64_t block) const {
  uint64_t n = 0;
  for (const uint64_t b : pieces_.at(size_t(block))) n += b;
  return n;
}

uint64_t BlockStream::host_bytes() const {
  uint64_t n = 0;
  for (int64_t j = 0; j < blocks(); ++j) n += block_bytes(j);
  return n;
}

bool BlockStream::has(int64_t block, const std::string& name) const {
  return block >= 0 && block < blocks() && layout_[size_t(block)].count(name) != 0;
}

Tensor BlockStream::get(int64_t block, const std::string& name) const {
  if (!has(block, name)) throw Error("internal: " + what_ + ": block " + std::to_string(block) + " streams no '" + name + "'");
  const Entry& e = layout_[size_t(block)].at(name);
  const uint64_t bytes = uint64_t(shape_numel(e.shape)) * dtype_size(e.dtype);
  return Tensor::on(slots_[size_t(block) % slots_.size()][e.piece].view().sub(e.offset, bytes), e.shape, e.dtype);
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
  std::vector<vk::UploadQueue::Copy> copies;
  for (size_t k = 0; k < pieces_[size_t(block)].size(); ++k)
    copies.push_back({host_[size_t(block)][k].view(), slots_[slot][k].view(), pieces_[size_t(block)][k]});
  const uint64_t value = uploads_.upload(copies, after_compute, stamps_.get(), uint32_t(4 * block));
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
    if (stamps_ && j >= 1) stamps_->mark(uint32_t(4 * (j - 1) + 3));  // block j − 1's segments have run
    // Block j − 1 was the last to read slot (j + k − 1) % k: its segments are the compute submitted so far.
    const int64_t next = j + k - 1;
    if (j >= 1 && next < n && upload_value_[size_t(next)] == 0) upload(next, ctx_.submission_count());
    if (upload_value_[size_t(j)] == 0)
      throw Error("internal: " + what_ + ": block " + std::to_string(j) + " starts before its upload was scheduled");
    if (stamps_) {  // block j's compute starts: its upload done
      ctx_.wait_before_next(uploads_.timeline(), upload_value_[size_t(j)]);
      stamps_->mark(uint32_t(4 * j + 2));
    }
    ctx_.wait_before_next(uploads_.timeline(), upload_value_[size_t(j)]);
    events_.push_back({StreamEvent::Kind::compute, j, uint32_t(size_t(j) % slots_.size()), upload_value_[size_t(j)],
                       ctx_.submission_count() + 1, ctx_.submission_count()});
  }
}

void BlockStream::record_timestamps() {
  if (ctx_.has_transfer_queue())
    throw Error(what_ + ": GPU timestamps of the uploads (a transfer queue) and of the compute do not compare");
  if (!stamps_) stamps_ = std::make_unique<vk::TimestampQueries>(ctx_, uint32_t(4 * blocks()));
}

std::vector<BlockTimes> BlockStream::block_times() const {
  std::vector<BlockTimes> out;
  if (!stamps_) return out;
  for (int64_t j = 0; j < blocks(); ++j) {
    if (upload_value_.size() != size_t(blocks()) || upload_value_[size_t(j)] == 0)
      throw Error("internal: " + what_ + ": block_times before a whole call ran");
    const std::vector<double> t = stamps_->read_ns(uint32_t(4 * j), j + 1 < blocks() ? 4 : 3);
    out.push_back({t[0], t[1], t[2], j + 1 < blocks() ? t[3] : 0.0});
  }
  return out;
}

}  // namespace dvs::models
