#include "pipeline/memory_advice.hpp"

#include <algorithm>

#include "pipeline/job_stages.hpp"
#include "io/option_names.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"

namespace dvs {
namespace {

std::string hw(int64_t h, int64_t w) { return std::to_string(h) + "x" + std::to_string(w); }

// The plan's model call that runs in a run stage ("" when the stage runs no model call of the plan).
std::string plan_stage_of(const std::string& stage) {
  if (stage == "encode") return "vae_encode";
  if (stage == "decode") return "vae_decode";
  if (stage == "text") return "t5_encode";
  if (stage == "invert") return "transformer_inversion";
  if (stage == "sample") return "transformer_cfg";
  return "";
}

// Which option lowers the memory of `stage`, from the plan's own tiling offers for the VAE stages.
std::string what_helps(const std::string& stage, const pipeline::MemoryPlan& plan, bool tiled) {
  const std::string tile = option_name("RunOptions::vae_tile_height/width"), size = option_name("RenderJob::height/width"),
                    frames = option_name("RenderJob::frames");
  const std::string smaller = "a smaller " + size + " or fewer " + frames;
  if (stage == "encode" || stage == "decode") {
    const bool enc = stage == "encode";
    const pipeline::TilingOption* best = nullptr;  // the tiling whose call needs least
    for (size_t i = 1; i < plan.tilings.size(); ++i) {
      const auto& t = plan.tilings[i];
      if (!best || (enc ? t.vae_encode.total() < best->vae_encode.total() : t.vae_decode.total() < best->vae_decode.total()))
        best = &t;
    }
    if (best && !tiled)
      return tile + " " + hw(best->tiling.tile_sample_min_height, best->tiling.tile_sample_min_width) +
             " (the VAE " + (enc ? "encode" : "decode") + " then needs " +
             pipeline::format_plan_bytes(enc ? best->vae_encode.total() : best->vae_decode.total()) + ", the run " +
             pipeline::format_plan_bytes(best->run_peak) + "), or " + smaller;
    return "a smaller " + tile + ", " + smaller;
  }
  // Streaming the model's blocks leaves two of them on the device (limits.md#weight-streaming).
  auto streaming = [&](const char* component) -> std::string {
    for (const auto& st : plan.streams)
      if (st.component == component && !st.streamed)
        return option_name("RunOptions::weights") + " stream (its blocks then hold " + pipeline::format_plan_bytes(st.device_bytes()) +
               " of device memory instead of all of them), or ";
    return "";
  };
  if (stage == "text")
    return streaming("text_encoder") + "freeing the device memory other programs hold, or a device with more memory "
           "(T5's needs do not depend on the video's size)";
  if (stage == "invert" || stage == "sample")
    return streaming("transformer") + smaller + " (the transformer's attention grows with both; VAE tiling does not change this stage)";
  if (stage == "depth")
    return "a smaller " + option_name("RenderJob::depth_input_size") + " (dvs depth: --input-size or --max-res)";
  return smaller;
}

}  // namespace

pipeline::PlanRequest run_plan_request(const RunOptions& o, const vk::DeviceCaps& dev) {
  pipeline::PlanRequest req;
  req.frames = o.render.frames, req.height = o.render.height, req.width = o.render.width;
  req.alignment = std::max<uint64_t>(256, dev.min_storage_buffer_offset_alignment);
  if (dev.memory_budget.bytes) req.budget = dev.memory_budget.bytes;
  req.limits = pipeline::PlanLimits{"device " + std::to_string(dev.index) + " (" + dev.name + ")" +
                                        (dev.forced_limits.any() ? " lowered by DVS_LIMITS" : ""),
                                    dev.max_storage_buffer_range, dev.max_texel_buffer_elements,
                                    dev.max_memory_allocation_size, dev.max_workgroup_count[0]};
  req.hard_points = o.render.hard_points;
  req.tiling = vae_tiling(o);
  req.weights = pipeline::parse_weights_choice(o.weights, option_name("RunOptions::weights"));
  req.limits->transfer_queue = dev.transfer_queue_family >= 0;
  return req;
}

std::string out_of_memory_advice(const RunOptions& o, const std::string& stage) {
  try {
    const std::vector<vk::DeviceCaps> devices = vk::list_devices();
    const vk::DeviceCaps& dev = devices.at(vk::select_device(devices, o.render.device));
    const pipeline::PlanRequest req = run_plan_request(o, dev);
    const pipeline::MemoryPlan plan = pipeline::plan_memory(pipeline::plan_model_from_folder(o.model), req);
    const pipeline::TilingOption& mine = plan.tilings[req.tiling ? 1 : 0];
    std::string text = "; dvs plan for this run on " + dev.name + " (" + pipeline::format_plan_bytes(dev.memory_budget.bytes) +
                       " for dvs): ";
    const std::string call = plan_stage_of(stage);
    const models::StageMemory* st = nullptr;
    if (call == "vae_encode") st = &mine.vae_encode;
    else if (call == "vae_decode") st = &mine.vae_decode;
    for (const auto& s : plan.stages)
      if (!st && s.name == call) st = &s;
    if (st) text += "the " + stage + " stage's " + st->name + " call needs " + pipeline::format_plan_bytes(st->total()) + ", ";
    text += "the run's peak is " + pipeline::format_plan_bytes(mine.run_peak) +
            (req.tiling ? " with " + option_name("RunOptions::vae_tile_height/width") + " " + hw(mine.tiling.tile_sample_min_height, mine.tiling.tile_sample_min_width)
                        : std::string(" untiled")) +
            (mine.blocker.empty() ? " (the plan expected it to fit: other programs may be using the device's memory)"
                                  : " (" + mine.blocker + ")") +
            ". Try " + what_helps(stage, plan, req.tiling.has_value()) + "; dvs plan --device shows every stage";
    return text;
  } catch (const std::exception&) {
    return vk::kOutOfMemoryHint;
  }
}

}  // namespace dvs
