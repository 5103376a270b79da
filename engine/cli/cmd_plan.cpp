// `dvs plan`: the device memory a run needs, from the model's config.json files alone (no weights loaded, no
// device opened).
#include <algorithm>
#include <iostream>

#include "args.hpp"
#include "depth_args.hpp"
#include "commands.hpp"
#include "dvs/error.hpp"
#include "models/vda/vda_model.hpp"
#include "pipeline/memory_plan.hpp"
#include "vk/context.hpp"
#include "vk/device_info.hpp"
#include "vk/device_limits.hpp"
#include "vk/limit_profiles.hpp"

namespace dvs::cli {

static const char* kPlanHelp =
    "usage: dvs plan --model DIR|cogvideox-5b-i2v [--frames 49] [--height 480] [--width 720] [--budget SIZE]\n"
    "                [--device N|NAME | --limits PROFILE] [--alignment 256] [--json]\n"
    "                [--depth-model FILE|vits|vitb|vitl [--depth-input-size 518] [--video-size HxW]]\n"
    "\n"
    "Plans device memory from the config.json files (safetensors headers are read for the stored weight bytes\n"
    "when present; no tensor data is read, no device is opened). Prints the weight bytes per component, the\n"
    "peak of each model call (T5 encode of the 2 prompts, the transformer with the CFG batch of 2 and with\n"
    "batch 1 for inversion, VAE encode of the clip, VAE decode of the latent), the peak of the whole run with\n"
    "every weight resident, and with --budget the VAE spatial tiling that fits. With --device or --limits it\n"
    "also checks each stage's largest tensor against the device's limits (bindings and texel views are split\n"
    "by the ops; each tensor must fit one allocation) and recommends only a setting that runs there.\n"
    "\n"
    "  --model DIR|NAME   a model folder laid out like THUDM/CogVideoX-5b-I2V, or the built-in\n"
    "                     'cogvideox-5b-i2v' (the real configuration, bf16 weights; nothing downloaded)\n"
    "  --frames N         clip frames, 4k+1 (default 49)\n"
    "  --height H         clip height in pixels (default 480)\n"
    "  --width W          clip width in pixels (default 720)\n"
    "  --budget SIZE      device memory available: 24GiB, 80GB, 512MiB or bytes\n"
    "  --device N|NAME    plan for this Vulkan device: its limits (lowered by DVS_LIMITS) and, without --budget,\n"
    "                     the memory dvs may hold on it (dvs info shows both)\n"
    "  --limits PROFILE   plan for a typical device: lavapipe, nvidia, amd, intel, apple or min (the Vulkan\n"
    "                     specification's minimums; DVS_LIMITS lowers them); without --budget, the profile's memory\n"
    "  --alignment N      the allocator's alignment in bytes (default 256; dvs info shows the device's limits)\n"
    "  --json             one JSON object instead of the table\n"
    "  --depth-model M    include the depth estimate of run --depth-model (it runs first, alone): a checkpoint\n"
    "                     (only its tensor list is read) or a released size vits, vitb, vitl\n"
    "  --depth-input-size N   its network input's short side (default 518)\n"
    "  --video-size HxW   the video's frames, which the depth is estimated at (default: the clip size)\n"
    "\n"
    "Exit status 1 when a budget, --device or --limits is given and no setting runs within them.\n";

int run_plan(const std::vector<std::string>& argv) {
  Args a("plan", argv,
         {"model", "frames", "height", "width", "budget", "alignment", "device", "limits", "depth-model",
          "depth-input-size", "video-size"},
         {"json"});
  if (a.help()) {
    std::cout << kPlanHelp;
    return 0;
  }
  const std::string model = a.required("model");
  pipeline::PlanRequest req;
  req.frames = a.integer("frames", 49, 1, 100001);
  req.height = a.integer("height", 480, 1, 1 << 16);
  req.width = a.integer("width", 720, 1, 1 << 16);
  req.alignment = uint64_t(a.integer("alignment", 256, 1, 1 << 20));
  if (a.has("budget")) {
    try {
      req.budget = pipeline::parse_byte_size(a.str("budget"), "--budget");
    } catch (const Error& e) {
      a.fail(e.what());  // a malformed option value is a usage error (exit 2)
    }
  }
  if (a.has("depth-model")) {
    const std::string m = a.str("depth-model");
    req.depth_model = (m == "vits" || m == "vitb" || m == "vitl") ? released_vda_config(m) : VdaModel::inspect(m);
    req.depth_input_size = depth_input_size(a, "depth-input-size", 518);
    const auto [vh, vw] = a.size("video-size", {0, 0});
    req.depth_frame_height = vh, req.depth_frame_width = vw;
  } else if (a.has("depth-input-size") || a.has("video-size")) {
    a.fail("--depth-input-size and --video-size need --depth-model");
  }
  if (a.has("device") && a.has("limits")) a.fail("give --device or --limits, not both");
  uint64_t limits_heap = 0;
  if (a.has("limits")) {
    const vk::LimitProfile* p = nullptr;
    try {
      p = &vk::limit_profile(a.str("limits"));
    } catch (const Error& e) {
      a.fail(std::string("--limits: ") + e.what());
    }
    req.limits = pipeline::PlanLimits{"profile " + p->name + " (" + p->describes + ")", p->binding, p->texels, p->alloc,
                                      p->groups[0]};
    // DVS_LIMITS lowers a profile as it lowers a device.
    const vk::LimitOverrides env = vk::limit_overrides_from_env();
    if (env.binding) req.limits->binding = std::min(req.limits->binding, *env.binding);
    if (env.texels) req.limits->texels = std::min(req.limits->texels, *env.texels);
    if (env.alloc) req.limits->alloc = std::min(req.limits->alloc, *env.alloc);
    if (env.groups) req.limits->groups = uint32_t(std::min<uint64_t>(req.limits->groups, *env.groups));
    if (env.any()) req.limits->source += " lowered by DVS_LIMITS";
    req.alignment = std::max<uint64_t>(req.alignment, p->alignment);
    limits_heap = p->heap;
  }
  if (a.has("device")) {
    const std::vector<vk::DeviceCaps> devices = vk::list_devices();  // DVS_LIMITS lowers them, as for a run
    const vk::DeviceCaps& d = devices.at(vk::select_device(devices, a.str("device")));
    req.limits = pipeline::PlanLimits{"device " + std::to_string(d.index) + " (" + d.name + ")", d.max_storage_buffer_range,
                                      d.max_texel_buffer_elements, d.max_memory_allocation_size, d.max_workgroup_count[0]};
    req.alignment = std::max<uint64_t>(req.alignment, d.min_storage_buffer_offset_alignment);
    limits_heap = d.memory_budget.bytes;
  }
  if (!req.budget && limits_heap) req.budget = limits_heap;
  const pipeline::PlanModel pm =
      pipeline::is_builtin_model(model) ? pipeline::builtin_plan_model(model) : pipeline::plan_model_from_folder(model);
  const pipeline::MemoryPlan plan = pipeline::plan_memory(pm, req);
  if (a.has("json")) std::cout << pipeline::plan_to_json(plan).dump(2) << "\n";
  else std::cout << pipeline::format_plan_table(plan);
  return plan.checked() && plan.chosen < 0 ? 1 : 0;
}

}  // namespace dvs::cli
