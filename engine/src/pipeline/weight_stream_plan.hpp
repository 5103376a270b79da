// What streaming a component's block weights costs (dvs plan, `--weights stream`; models/block_stream.hpp):
// device slots instead of every block, the pinned host copy, the bytes each model call uploads, their time at
// the host -> device rate, and whether that time hides behind the compute of the blocks. From the config (and
// the safetensors headers when present) alone, as the rest of the plan.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "spec/model_schema.hpp"

namespace dvs::pipeline {

// What a run is told about the residency of the transformer's and T5's block weights (dvs run --weights).
enum class WeightsChoice { automatic, resident, stream };
const char* weights_choice_name(WeightsChoice c);                        // "auto", "resident", "stream"
WeightsChoice parse_weights_choice(const std::string& text, const std::string& option);  // throws UsageError

struct WeightStreamPlan {
  std::string component;        // "transformer", "text_encoder"
  bool streamed = false;        // the plan's choice for this run
  int64_t blocks = 0;
  int slots = 2;
  uint64_t slot_bytes = 0;      // the largest block packed as the stream packs it: one device slot
  uint64_t host_bytes = 0;      // every block packed: the pinned host copy, and what one model call uploads
  uint64_t resident_bytes = 0;  // the component's other weights (embeddings, norms, projections): on the device
  uint64_t device_bytes() const { return resident_bytes + uint64_t(slots) * slot_bytes; }
  std::string calls;            // how often a call uploads every block: "per sampling or inversion step", "once"
  double block_flops = 0;       // one block's compute in the phase's call (transformer: the CFG batch of 2)
  // At the request's upload rate (when known): one call's upload, one block's, and the compute rate below
  // which a block computes for at least as long as the next one uploads (the upload hides).
  std::optional<double> call_upload_seconds, block_upload_seconds, break_even_flops;
  // Whether a block's compute at the device's peak rate (when known) lasts at least its upload, and whether the
  // upload then hides: that and a transfer queue to run it beside the compute. Without one, a step pays up to
  // call_upload_seconds more (the driver may still overlap copies and compute on one queue).
  std::optional<bool> compute_longer, hides;
  std::string verdict;          // one line on the overlap, for the table
};

// `prefix`: the block tensors' common prefix ("transformer_blocks.", "encoder.block."), the block index following;
// `keep`: block tensors that stay resident anyway (T5's relative position table). `stored`: bytes per tensor from
// the safetensors headers (empty: schema shapes x `assumed_dtype_bytes`). `alignment`: the allocator's.
WeightStreamPlan plan_weight_stream(const std::string& component, const Schema& schema, const std::string& prefix,
                                    const std::map<std::string, uint64_t>& stored, int assumed_dtype_bytes,
                                    const std::string& keep, uint64_t alignment, int slots);

// Fills the timing fields: `block_flops` of one block; `rate` host -> device bytes/s, `peak` the device's flop/s,
// `transfer_queue` whether it copies beside the compute (each when known).
void time_weight_stream(WeightStreamPlan& s, double block_flops, std::optional<double> rate, std::optional<double> peak,
                        std::optional<bool> transfer_queue);

}  // namespace dvs::pipeline
