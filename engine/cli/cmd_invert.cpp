// `dvs invert`: render, VAE-encode and DDIM-invert only. Writes ε_inv and fills the inversion cache, so a
// later `dvs run` with the same inputs and inversion settings (any prompt, guidance, k or seed) starts at
// the sampling.
#include <iostream>

#include "args.hpp"
#include "commands.hpp"
#include "dvs/pipeline.hpp"
#include "interrupt.hpp"
#include "progress.hpp"
#include "run_command.hpp"

namespace dvs::cli {
namespace {

const char* kInvertHelp =
    "usage: dvs invert --video V (--depth D | --depth-model FILE.pth) --model DIR --out DIR [options]\n"
    "\n"
    "Stages 1-5 of dvs run: renders V along the camera path, VAE-encodes the render and DDIM-inverts it with the\n"
    "transformer up to the start timestep t0. Writes DIR/eps_inv.npy ([latent frames, C, h, w] f32) and stores\n"
    "the result in the inversion cache, where dvs run with the same inputs, model, LoRA, tiling, --preset,\n"
    "--steps, --strength and --inversion-steps finds it (any --prompt, --guidance, --k, --delta or --seed).\n"
    "\n"
    "Takes dvs run's input, model, schedule, cache and memory options (dvs run --help): --video --depth --depth-model\n"
    "--metric-depth --trim-depth --trajectory --frames --size|--height/--width --resize --intrinsics --points\n"
    "--model --preset --steps --strength --inversion-steps --lora --vae-tiling --vae-tile --cache-dir --no-cache\n"
    "--device --progress --quiet\n";

// run's options that do not change ε_inv are not taken, so a user cannot believe they did.
std::set<std::string> invert_options() {
  std::set<std::string> o = kRunOptions;
  for (const char* name : {"prompt", "negative-prompt", "guidance", "k", "delta", "seed", "dynamic-cfg", "preservation-scale"}) o.erase(name);
  return o;
}

}  // namespace

int run_invert(const std::vector<std::string>& argv) {
  Args a("invert", argv, invert_options(), kRunFlags);
  if (a.help()) {
    std::cout << kInvertHelp;
    return 0;
  }
  const RunOptions o = parse_run_options(a);
  const ProgressMode mode = progress_mode(a);
  Progress progress(mode);
  InversionReport r = run_inversion(o, std::ref(progress), interrupted);
  progress.finish();
  print_stage_times(mode, r.stages, r.from_cache);
  std::cout << "wrote " << r.eps_inv_npy.string() << " [";
  for (size_t i = 0; i < r.shape.size(); ++i) std::cout << (i ? "," : "") << r.shape[i];
  std::cout << "] (t0 = " << r.t0 << ")\n";
  if (!r.cache_file.empty()) std::cout << "cached " << r.cache_file.string() << "\n";
  return 0;
}

}  // namespace dvs::cli
