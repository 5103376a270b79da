// `dvs invert`: render, VAE-encode and DDIM-invert only. Writes ε_inv and fills the inversion cache, so a
// later `dvs run` with the same inputs and inversion settings (any prompt, guidance, k or seed) starts at
// the sampling.
#include <iostream>

#include "args.hpp"
#include "commands.hpp"
#include "dvs/pipeline.hpp"
#include "interrupt.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "run_command.hpp"

namespace dvs::cli {
namespace {

const CommandHelp kInvertHelp{
    "dvs invert --video V (--depth D | --depth-model FILE.pth) --model DIR --out DIR [options]",
    "Stages 1-5 of dvs run: renders V along the camera path, VAE-encodes the render and DDIM-inverts it with the\n"
    "transformer up to the start timestep t0. Writes DIR/eps_inv.npy ([latent frames, C, h, w] f32) and stores\n"
    "the result in the inversion cache, where dvs run with the same inputs, model, LoRA, tiling, --preset,\n"
    "--steps, --strength and --inversion-steps finds it (any --prompt, --guidance, --k, --delta or --seed).\n"
    "Takes dvs run's options except the prompt and sampling ones, which do not change the inversion.\n",
    ""};

}  // namespace

int run_invert(const std::vector<std::string>& argv) {
  Args a("invert", kInvertHelp, invert_option_groups());
  a.parse(argv);
  if (a.help()) return 0;
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
