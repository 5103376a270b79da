// `dvs plan`: the device memory a run needs, from the model's config.json files alone (no weights loaded, no
// device opened).
#include <iostream>

#include "args.hpp"
#include "commands.hpp"
#include "dvs/error.hpp"
#include "pipeline/memory_plan.hpp"

namespace dvs::cli {

static const char* kPlanHelp =
    "usage: dvs plan --model DIR|cogvideox-5b-i2v [--frames 49] [--height 480] [--width 720] [--budget SIZE]\n"
    "                [--alignment 256] [--json]\n"
    "\n"
    "Plans device memory from the config.json files (safetensors headers are read for the stored weight bytes\n"
    "when present; no tensor data is read, no device is opened). Prints the weight bytes per component, the\n"
    "peak of each model call (T5 encode of the 2 prompts, the transformer with the CFG batch of 2 and with\n"
    "batch 1 for inversion, VAE encode of the clip, VAE decode of the latent), the peak of the whole run with\n"
    "every weight resident, and with --budget the VAE spatial tiling that fits.\n"
    "\n"
    "  --model DIR|NAME   a model folder laid out like THUDM/CogVideoX-5b-I2V, or the built-in\n"
    "                     'cogvideox-5b-i2v' (the real configuration, bf16 weights; nothing downloaded)\n"
    "  --frames N         clip frames, 4k+1 (default 49)\n"
    "  --height H         clip height in pixels (default 480)\n"
    "  --width W          clip width in pixels (default 720)\n"
    "  --budget SIZE      device memory available: 24GiB, 80GB, 512MiB or bytes\n"
    "  --alignment N      the allocator's alignment in bytes (default 256; dvs info shows the device's limits)\n"
    "  --json             one JSON object instead of the table\n";

int run_plan(const std::vector<std::string>& argv) {
  Args a("plan", argv, {"model", "frames", "height", "width", "budget", "alignment"}, {"json"});
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
  const pipeline::PlanModel pm =
      pipeline::is_builtin_model(model) ? pipeline::builtin_plan_model(model) : pipeline::plan_model_from_folder(model);
  const pipeline::MemoryPlan plan = pipeline::plan_memory(pm, req);
  if (a.has("json")) std::cout << pipeline::plan_to_json(plan).dump(2) << "\n";
  else std::cout << pipeline::format_plan_table(plan);
  return 0;
}

}  // namespace dvs::cli
