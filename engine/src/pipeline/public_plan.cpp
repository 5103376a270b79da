// dvs/plan.hpp on the memory planner (pipeline/memory_plan): the request checked against the model first, so a
// size the model cannot take is the caller's usage error, not a failure of the plan.
#include "dvs/plan.hpp"

#include <algorithm>
#include <filesystem>

#include "io/public_call.hpp"
#include "dvs/usage_error.hpp"
#include "io/option_names.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/vda/vda_model.hpp"
#include "pipeline/memory_plan.hpp"

namespace dvs {
namespace {

// The checks plan_memory makes on the request, as usage errors: the VAE compresses time by 4 after the first
// frame, and a frame must be whole latent patches.
void require_plannable(const pipeline::PlanModel& pm, const MemoryPlanRequest& req) {
  if (req.frames < 1 || (req.frames - 1) % 4 != 0)
    throw UsageError(option_name("MemoryPlanRequest::frames") + " must be 4k+1 (1, 5, 9, ..., 49), got " + std::to_string(req.frames) +
                     ": the VAE compresses time by 4 after the first frame");
  if (req.alignment == 0 || (req.alignment & (req.alignment - 1)) != 0)
    throw UsageError(option_name("MemoryPlanRequest::alignment") + " must be a power of two, got " + std::to_string(req.alignment));
  const std::string height = option_name("MemoryPlanRequest::height"), width = option_name("MemoryPlanRequest::width");
  const auto tcfg = models::CogVideoXTransformerConfig::from_json(pm.transformer, "transformer config");
  const int64_t r = models::VaeConfig::from_json(pm.vae).spatial_ratio(), cell = r * tcfg.patch_size;
  if (req.height < cell || req.width < cell || req.height % cell || req.width % cell)
    throw UsageError(height + " and " + width + " must be positive multiples of " + std::to_string(cell) + " for " + pm.source +
                     " (VAE ratio " + std::to_string(r) + " x patch " + std::to_string(tcfg.patch_size) + "), got " +
                     std::to_string(req.height) + "x" + std::to_string(req.width) + "; e.g. " +
                     std::to_string(std::max(cell, req.height / cell * cell)) + "x" +
                     std::to_string(std::max(cell, req.width / cell * cell)));
  const int64_t fixed_h = tcfg.sample_height * r, fixed_w = tcfg.sample_width * r;
  if (tcfg.learned_pos && (req.height != fixed_h || req.width != fixed_w))
    throw UsageError(height + " " + std::to_string(req.height) + " " + width + " " + std::to_string(req.width) + ": " +
                     pm.source + " has a learned positional table, which fixes the size to " + std::to_string(fixed_h) +
                     "x" + std::to_string(fixed_w) + " (its transformer rejects any other); plan " + height + " " +
                     std::to_string(fixed_h) + " " + width + " " + std::to_string(fixed_w) + " with any 4k+1 " +
                     option_name("MemoryPlanRequest::frames"));
}

// The model a request names: a built-in configuration or a folder. A name that is both (a folder called
// cogvideox-5b-i2v in the current folder) is refused rather than one of them silently chosen.
pipeline::PlanModel plan_model(const std::string& model) {
  std::error_code ec;
  const bool folder = std::filesystem::is_directory(model, ec);
  if (!pipeline::is_builtin_model(model)) return pipeline::plan_model_from_folder(model);
  if (folder)
    throw UsageError(option_name("MemoryPlanRequest::model") + " " + model +
                     " names both the built-in configuration and the folder " + model + ": give ./" + model +
                     " for the folder, or run dvs plan from another folder for the " +
                     "built-in configuration");
  return pipeline::builtin_plan_model(model);
}

// --depth-model: a released size, or a checkpoint file.
VdaConfig depth_model_config(const std::string& m) {
  if (m == "vits" || m == "vitb" || m == "vitl") return released_vda_config(m);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(m, ec))
    throw UsageError(option_name("MemoryPlanRequest::depth_model") + " " + m + ": no such checkpoint file, and not a released size (vits, vitb or vitl)");
  return VdaModel::inspect(m);
}

}  // namespace

bool is_builtin_model(const std::string& name) { return pipeline::is_builtin_model(name); }

uint64_t parse_byte_size(const std::string& text, const std::string& option) {
  try {
    return pipeline::parse_byte_size(text, option);
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    throw UsageError(e.what());  // a malformed size is the caller's to fix
  }
}

MemoryPlanReport plan_run_memory(const MemoryPlanRequest& request) {
  return public_call("dvs::plan_run_memory", [&]() -> MemoryPlanReport {
    const pipeline::PlanModel pm = plan_model(request.model);
    require_plannable(pm, request);
    pipeline::PlanRequest req;
    req.frames = request.frames, req.height = request.height, req.width = request.width;
    req.budget = request.budget;
    req.alignment = request.alignment;
    if (request.limits) {
      const DeviceLimits& l = *request.limits;
      req.limits = pipeline::PlanLimits{l.source, l.binding, l.texels, l.alloc, l.groups};
      if (l.upload_bytes_per_second > 0) req.limits->upload_rate = l.upload_bytes_per_second;
      if (l.peak_flops > 0) req.limits->peak_flops = l.peak_flops;
      if (l.transfer_queue >= 0) req.limits->transfer_queue = l.transfer_queue == 1;
      req.alignment = std::max(req.alignment, l.alignment);
      if (!req.budget && l.memory) req.budget = l.memory;
    }
    if (!request.depth_model.empty()) {
      const std::string& m = request.depth_model;
      req.depth_model = depth_model_config(m);
      req.depth_input_size = request.depth_input_size;
      req.depth_frame_height = request.depth_frame_height, req.depth_frame_width = request.depth_frame_width;
    }
    req.weights = pipeline::parse_weights_choice(request.weights, option_name("MemoryPlanRequest::weights"));
    if (!(request.upload_bytes_per_second >= 0))  // negative or NaN
      throw UsageError(option_name("MemoryPlanRequest::upload_bytes_per_second") + " is " +
                       std::to_string(request.upload_bytes_per_second) +
                       ": give the host -> device rate in bytes per second, or 0 for the limits' figure");
    if (request.upload_bytes_per_second > 0) req.upload_rate = request.upload_bytes_per_second;
    const pipeline::MemoryPlan plan = pipeline::plan_memory(pm, req);
    MemoryPlanReport r;
    r.checked = plan.checked();
    r.runs = !plan.checked() || plan.chosen >= 0;
    r.weights_bytes = plan.weights_total;
    r.run_peak_bytes = plan.run_peak;
    r.table = pipeline::format_plan_table(plan);
    r.json = pipeline::plan_to_json(plan).dump(2);
    return r;
  });
}

}  // namespace dvs
