#include "pipeline/weight_stream_plan.hpp"

#include <algorithm>
#include <cstdio>
#include <vector>

#include "dvs/usage_error.hpp"
#include "models/call_memory.hpp"

namespace dvs::pipeline {

const char* weights_choice_name(WeightsChoice c) {
  return c == WeightsChoice::resident ? "resident" : c == WeightsChoice::stream ? "stream" : "auto";
}

WeightsChoice parse_weights_choice(const std::string& text, const std::string& option) {
  if (text == "auto") return WeightsChoice::automatic;
  if (text == "resident") return WeightsChoice::resident;
  if (text == "stream") return WeightsChoice::stream;
  throw UsageError(option + " must be resident, stream or auto, got '" + text + "'");
}

WeightStreamPlan plan_weight_stream(const std::string& component, const Schema& schema, const std::string& prefix,
                                    const std::map<std::string, uint64_t>& stored, int assumed_dtype_bytes,
                                    const std::string& keep, uint64_t alignment, int slots) {
  std::map<std::string, uint64_t> bytes = stored;
  if (bytes.empty())
    for (const auto& t : schema.tensors)
      if (!t.optional) bytes[t.name] = uint64_t(shape_numel(t.shape)) * uint64_t(assumed_dtype_bytes);
  WeightStreamPlan s;
  s.component = component;
  s.slots = slots;
  std::vector<uint64_t> packed;  // per block, each tensor aligned as BlockStream packs it
  for (const auto& [name, n] : bytes) {
    int64_t block = -1;
    if (name.rfind(prefix, 0) == 0 && name != keep) {
      const size_t dot = name.find('.', prefix.size());
      try {
        block = std::stoll(name.substr(prefix.size(), dot - prefix.size()));
      } catch (const std::exception&) {
        block = -1;
      }
    }
    if (block < 0) {
      s.resident_bytes += n;
      continue;
    }
    if (packed.size() <= size_t(block)) packed.resize(size_t(block) + 1, 0);
    packed[size_t(block)] += models::align_up(std::max<uint64_t>(n, 1), alignment);
  }
  s.blocks = int64_t(packed.size());
  s.slots = int(std::min<int64_t>(slots, std::max<int64_t>(s.blocks, 1)));  // as BlockStream: no more slots than blocks
  for (const uint64_t b : packed) {
    s.host_bytes += b;
    s.slot_bytes = std::max(s.slot_bytes, b);
  }
  return s;
}

void time_weight_stream(WeightStreamPlan& s, double block_flops, std::optional<double> rate, std::optional<double> peak,
                        std::optional<bool> transfer_queue) {
  s.block_flops = block_flops;
  char line[320];
  if (!rate || *rate <= 0 || s.blocks == 0) {
    s.verdict = "upload time unknown: give the device's host -> device rate (dvs info --bench-upload, then "
                "dvs plan --upload-rate)";
    return;
  }
  s.call_upload_seconds = double(s.host_bytes) / *rate;
  s.block_upload_seconds = double(s.slot_bytes) / *rate;
  s.break_even_flops = block_flops / *s.block_upload_seconds;
  if (peak && *peak > 0) {
    const double at_peak = block_flops / *peak;  // a block's compute at the device's peak: the least it takes
    const bool compute_longer = at_peak >= *s.block_upload_seconds;
    const bool beside = transfer_queue.value_or(false);
    s.compute_longer = compute_longer;
    s.hides = compute_longer && beside;
    std::snprintf(line, sizeof line, "a block computes for at least %.3g ms at the peak %.4g TFLOP/s, its upload takes %.3g ms: %s",
                  at_peak * 1e3, *peak / 1e12, *s.block_upload_seconds * 1e3,
                  !compute_longer ? "the upload is longer, streaming is upload-bound"
                  : beside        ? "the upload hides behind the compute (transfer queue)"
                                  : "longer than the upload, but without a transfer-only queue the copies share the "
                                    "compute queue and the driver may run them in turn");
  } else {
    std::snprintf(line, sizeof line,
                  "the upload hides while a block computes for at least %.3g ms, i.e. at %.4g TFLOP/s or slower "
                  "(the device's peak is not known here)%s",
                  *s.block_upload_seconds * 1e3, *s.break_even_flops / 1e12,
                  transfer_queue && !*transfer_queue
                      ? ", and only where the driver overlaps copies and compute on its one queue (no transfer-only family)"
                      : "");
  }
  s.verdict = line;
}

}  // namespace dvs::pipeline
