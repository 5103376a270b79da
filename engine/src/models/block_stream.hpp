// Weights of a model's repeated blocks (transformer blocks, T5 layers) streamed from host memory behind the
// compute (`--weights stream`, docs/limits.md#weight-streaming), for devices whose memory does not hold them all.
//
// Host side: each block's tensors packed, in their stored dtype, into one buffer of pinned host memory the device
// reads directly (vk::MemoryUse::pinned), copied once from the mapped safetensors (or from the device, for weights
// made there); nothing is converted per step. Device side: `slots` slots as large as the largest block; block j
// computes from slot j % slots, its tensors at the same offsets as in its host buffer. A block larger than one
// allocation is packed over several pieces as an arena packs tensors (vk::ArenaPacking): a slot is one buffer per
// piece, and a block's upload copies every piece in one submission.
//
// Schedule of one model call (one recording, models place a Recorder::boundary after every block): before its
// first segment is submitted, the first `slots` blocks go up; before the first segment of block j (j ≥ 1) is
// submitted, block j + slots − 1 goes up into the slot block j − 1 used, its copy waiting on the GPU for the
// compute that last read that slot (the context's timeline), and block j's segment waits on the GPU for block
// j's upload (the upload queue's timeline). So block j + 1 uploads while block j computes, on a transfer queue
// where the device has one (vk::UploadQueue), and the host never waits for an upload. events() keeps the
// schedule of the last call: what each submission waited for, for tests and `dvs-bench`.
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "models/weights.hpp"
#include "tensor/tensor.hpp"
#include "vk/memory.hpp"
#include "vk/upload_queue.hpp"

namespace dvs::vk {
class Context;
class Recorder;
class TimestampQueries;
}  // namespace dvs::vk

namespace dvs::models {

// One submission of a streamed call, in submission order. Values are timeline values: the context's timeline
// counts compute submissions (Context::submission_count), the upload queue's counts uploads.
struct StreamEvent {
  enum class Kind { upload, compute } kind = Kind::upload;
  int64_t block = 0;
  uint32_t slot = 0;
  // upload: the compute value its copy waits for, the upload value it signals, and the last compute value
  // submitted before it. compute: the upload value its first segment waits for, and its own compute value.
  uint64_t waits_for = 0, value = 0, compute_submitted = 0;
};

// Where one block's upload and compute ran on the device's clock (ns), from record_timestamps. compute_end is
// taken when the next block's compute starts (the host has waited for this block's segments by then); the last
// block has none (0).
struct BlockTimes {
  double upload_start = 0, upload_end = 0, compute_start = 0, compute_end = 0;
};

class BlockStream {
 public:
  // The tensors `names(j)` of blocks j < blocks, taken out of `weights` into host memory (any device copy is
  // given back). `what` names the stream in errors ("transformer blocks"). `slots` ≥ 1, at most `blocks` are made;
  // 2 lets one block upload while the one before it computes.
  BlockStream(vk::Context& ctx, ComponentWeights& weights, int64_t blocks,
              const std::function<std::vector<std::string>(int64_t)>& names, int slots, std::string what);
  ~BlockStream();  // waits for the uploads still running
  BlockStream(const BlockStream&) = delete;
  BlockStream& operator=(const BlockStream&) = delete;

  int64_t blocks() const { return int64_t(layout_.size()); }
  int slots() const { return int(slots_.size()); }
  uint64_t slot_bytes() const;                                // device bytes of one slot (all its pieces)
  size_t slot_pieces() const { return slots_.front().size(); }  // allocations per slot (1 unless a block is larger)
  uint64_t block_bytes(int64_t block) const;                  // stored bytes one block uploads
  uint64_t host_bytes() const;                                // pinned host memory of every block
  bool has(int64_t block, const std::string& name) const;
  // Block `block`'s tensor `name`, a view into its slot (valid while this stream lives).
  Tensor get(int64_t block, const std::string& name) const;

  // Before recording a call into `rec`: installs the schedule above on it (Recorder::set_segment_start_hook).
  void begin_call(vk::Recorder& rec);
  // While recording: the commands recorded from here on belong to block `block` (before its first command).
  void mark_block(vk::Recorder& rec, int64_t block);

  const std::vector<StreamEvent>& events() const { return events_; }
  // Tests and dvs-bench: from the next call on, GPU timestamps of every upload (in its own command buffer) and of
  // every block's compute (marks submitted to the compute queue before its first segment, after its upload's
  // wait: they add to the context's timeline). Timestamps compare only on one queue, so this throws dvs::Error
  // on a device whose uploads go to a transfer queue of their own.
  void record_timestamps();
  std::vector<BlockTimes> block_times() const;  // of the last call, once it has run; empty without timestamps
  uint64_t uploads() const { return uploads_.submitted(); }  // uploads submitted since the stream was made

 private:
  struct Entry {
    size_t piece = 0;
    uint64_t offset = 0;
    Shape shape;
    DType dtype = DType::f32;
  };
  void on_segment(uint32_t segment);
  void upload(int64_t block, uint64_t after_compute);

  vk::Context& ctx_;
  std::string what_;
  std::vector<std::map<std::string, Entry>> layout_;  // per block
  std::vector<std::vector<uint64_t>> pieces_;         // per block, the bytes of each piece
  std::vector<std::vector<vk::Buffer>> host_;         // per block and piece, pinned
  std::vector<std::vector<vk::Buffer>> slots_;        // per slot and piece (each piece as large as any block's)
  vk::UploadQueue uploads_;
  // The call being submitted: the segment each block starts in, each block's upload value (0: not yet).
  std::vector<uint32_t> first_segment_;
  std::vector<uint64_t> upload_value_;
  bool started_ = false;
  std::vector<StreamEvent> events_;
  std::unique_ptr<vk::TimestampQueries> stamps_;  // 4 per block: upload start, end; compute start, end
};

}  // namespace dvs::models
