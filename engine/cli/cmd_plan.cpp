// `dvs plan`: the device memory a run needs, from the model's config.json files alone (no weights loaded, no
// device opened).
#include <iostream>
#include <tuple>

#include "args.hpp"
#include "depth_args.hpp"
#include "commands.hpp"
#include "dvs/error.hpp"
#include "dvs/plan.hpp"
#include "dvs/usage_error.hpp"
#include "options.hpp"

namespace dvs::cli {
namespace {

const CommandHelp kPlanHelp{
    "dvs plan --model DIR|cogvideox-5b-i2v [--frames 49] [--height 480] [--width 720] [--budget SIZE]\n"
    "                [--device N|NAME | --limits PROFILE] [--alignment 256] [--json]\n"
    "                [--weights auto|resident|stream] [--upload-rate RATE]\n"
    "                [--depth-model FILE|vits|vitb|vitl [--depth-input-size 518] [--video-size HxW]]",
    "Plans device memory from the config.json files (safetensors headers are read for the stored weight bytes\n"
    "when present; no tensor data is read, no device is opened). Prints the weight bytes per component, the\n"
    "peak of each model call (T5 encode of the 2 prompts, the transformer with the CFG batch of 2 and with\n"
    "batch 1 for inversion, VAE encode of the clip, VAE decode of the latent), the peak of the whole run with\n"
    "every weight resident, and with --budget the VAE spatial tiling that fits. With --device or --limits it\n"
    "also checks each stage's largest tensor against the device's limits (bindings and texel views are split\n"
    "by the ops; each tensor must fit one allocation) and recommends only a setting that runs there.\n"
    "For the transformer's and T5's block weights it prints what streaming them costs (device slots, the\n"
    "pinned host copy, the bytes each call uploads and their time at the upload rate, whether the upload\n"
    "hides behind the compute) and whether the run streams them (--weights auto: only where resident does\n"
    "not fit the budget).\n",
    "Exit status 1 when a budget, --device or --limits is given and no setting runs within them.\n"};

// dvs plan's own options: the clip's size in pixels of the plan (no video), and what it plans for.
const OptionGroup kPlanned{
    "plan",
    {{"model", "DIR|NAME",
      "a model folder laid out like THUDM/CogVideoX-5b-I2V, or the built-in\n"
      "'cogvideox-5b-i2v' (the real configuration, bf16 weights; nothing downloaded)"},
     {"frames", "N", "clip frames, 4k+1 (default 49)"},
     {"height", "H", "clip height in pixels (default 480)"},
     {"width", "W", "clip width in pixels (default 720)"},
     {"budget", "SIZE", "device memory available: 24GiB, 80GB, 512MiB or bytes"},
     {"limits", "PROFILE",
      "plan for a typical device: lavapipe, nvidia, amd, intel, apple or min (the\n"
      "Vulkan specification's minimums; DVS_LIMITS lowers them); without --budget,\n"
      "the profile's memory"},
     {"alignment", "N", "the allocator's alignment in bytes (default 256; dvs info shows the device's limits)"},
     {"weights", "MODE",
      "the block weights of the transformer and T5: auto (default: streamed only\n"
      "where resident does not fit the budget), resident or stream (as dvs run --weights)"},
     {"upload-rate", "RATE",
      "host -> device copy rate for the upload times, e.g. 12.5GB (per second;\n"
      "dvs info --bench-upload measures it); default: the profile's typical figure"},
     {"json", "", "one JSON object instead of the table"}}};

const OptionGroup kPlannedDepth{
    "depth estimate",
    {{"depth-model", "M",
      "include the depth estimate of run --depth-model (it runs first, alone): a\n"
      "checkpoint (only its tensor list is read) or a released size vits, vitb, vitl"},
     {"depth-input-size", "N", "its network input's short side (default 518)"},
     {"video-size", "HxW", "the video's frames, which the depth is estimated at (default: the clip size)"}}};

const OptionGroup kPlannedDevice{
    "device",
    {{"device", "N|NAME",
      "plan for this Vulkan device: its limits (lowered by DVS_LIMITS) and, without\n"
      "--budget, the memory dvs may hold on it (dvs info shows both)"}}};

}  // namespace

int run_plan(const std::vector<std::string>& argv) {
  Args a("plan", kPlanHelp, {kPlanned, kPlannedDepth, kPlannedDevice});
  a.parse(argv);
  if (a.help()) return 0;
  MemoryPlanRequest req;
  req.model = a.required("model");
  req.frames = a.integer("frames", 49, 1, 100001);
  req.height = a.integer("height", 480, 1, 1 << 16);
  req.width = a.integer("width", 720, 1, 1 << 16);
  req.alignment = uint64_t(a.integer("alignment", 256, 1, 1 << 20));
  if (!a.has("depth-model") && (a.has("depth-input-size") || a.has("video-size")))
    a.fail("--depth-input-size and --video-size need --depth-model");
  if (a.has("device") && a.has("limits")) a.fail("give --device or --limits, not both");
  if (a.has("depth-model")) {
    req.depth_model = a.str("depth-model");
    req.depth_input_size = depth_input_size(a, "depth-input-size", 518);
    std::tie(req.depth_frame_height, req.depth_frame_width) = a.size("video-size", {0, 0});
  }
  // The library's UsageErrors (a size it cannot read, a profile it does not know, frames or a size the model
  // cannot take) are this command line's to fix.
  try {
    if (a.has("budget")) req.budget = parse_byte_size(a.str("budget"), "--budget");
    if (a.has("weights")) req.weights = a.str("weights");
    if (a.has("upload-rate")) req.upload_bytes_per_second = double(parse_byte_size(a.str("upload-rate"), "--upload-rate"));
    if (a.has("limits")) req.limits = profile_limits(a.str("limits"));
    if (a.has("device")) req.limits = device_limits(a.str("device"));
    const MemoryPlanReport plan = plan_run_memory(req);
    std::cout << (a.has("json") ? plan.json + "\n" : plan.table);
    return plan.runs ? 0 : 1;
  } catch (const UsageError& e) {
    a.fail(e.what());
  }
}

}  // namespace dvs::cli
