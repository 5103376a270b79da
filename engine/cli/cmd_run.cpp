// `dvs run` (the whole pipeline on the user's video) and `dvs demo` (the same on a generated scene and a
// tiny random model).
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <tuple>

#include "args.hpp"
#include "commands.hpp"
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "io/lora_file.hpp"
#include "pipeline/duration_text.hpp"
#include "pipeline/preflight.hpp"
#include "pipeline/run_record.hpp"
#include "interrupt.hpp"
#include "depth_args.hpp"
#include "progress.hpp"
#include "prompt_length.hpp"
#include "run_command.hpp"

namespace dvs::cli {

const char* kRunHelp =
    "usage: dvs run --video V (--depth D | --depth-model FILE.pth) --model DIR --prompt TEXT --out DIR [options]\n"
    "\n"
    "Re-renders V along a new camera path: renders the input with its depth, VAE-encodes the render, inverts it\n"
    "with the transformer, fills occluded latents (SLM), initialises the noise (adaptive K-RNR) and samples the\n"
    "new view. Writes DIR/output.mp4, render.mp4, mask.mp4, comparison.mp4 (input | render | output) and run.json.\n"
    "\n"
    "inputs (as dvs render): --video --depth --metric-depth --trim-depth --depth-fit --trajectory\n"
    "  --depth-model FILE    instead of --depth: estimate the depth with Video-Depth-Anything (video_depth_anything_\n"
    "                        vits.pth etc., see README) before the diffusion models load; cached in the cache folder\n"
    "                        by the video's bytes, the model and the settings (--no-cache: estimate again)\n"
    "  --depth-input-size N  its network input's short side (default 518)\n"
    "  --frames N            4k+1, default 49\n"
    "  --size HxW or --height H --width W (default 480x720; multiples of 8; a model with learned positional\n"
    "                        embeddings, as CogVideoX-5B-I2V, needs its own size)\n"
    "  --resize crop|squash  --intrinsics fx,fy,cx,cy (default: f = 500 px at 1024x576, square pixels under crop,\n"
    "                        scaled per axis under squash)  --points\n"
    "  --model DIR           model folder laid out like THUDM/CogVideoX-5b-I2V\n"
    "  --prompt TEXT         what the scene shows\n"
    "  --negative-prompt T   default \"\" (paper) / the authors' fixed text (official)\n"
    "diffusion:\n"
    "  --preset paper|official  paper (default) or the authors' code (see README)\n"
    "  --steps N             sampling schedule length (paper 50, official 30)\n"
    "  --strength S          keeps the last floor(N*S) steps (paper 0.95, official 0.98)\n"
    "  --inversion-steps N   DDIM inversion steps (30)\n"
    "  --k K                 K-RNR order (10; real values allowed)\n"
    "  --delta D             AdaIN target order (paper 3, official 2)\n"
    "  --guidance G          classifier-free guidance scale (6)\n"
    "  --dynamic-cfg on|off  the authors' position-wise guidance: occluded latents get a per-step scale from G,\n"
    "                        fully visible ones --preservation-scale (official on, paper off: constant G)\n"
    "  --preservation-scale P  guidance scale of the fully visible latents with --dynamic-cfg on (1 = the\n"
    "                        prompt-conditioned prediction, as the authors' config)\n"
    "  --seed N              seed of every random draw (42)\n"
    "  --lora FILE[:SCALE]   a LoRA adapter (.safetensors, diffusers/PEFT layout) on the transformer, for the\n"
    "                        inversion and the sampling (scale 1 when not given)\n"
    "  --cache-dir DIR       inversion cache (default $DVS_CACHE_DIR or ~/.cache/dvs); --no-cache disables it\n"
    "memory:\n"
    "  --vae-tiling          encode and decode in overlapping spatial tiles (diffusers' enable_tiling): far less\n"
    "                        device memory at 480x720; use it when a run stops out of device memory\n"
    "  --vae-tile HxW        tile size in pixels (implies --vae-tiling; default half the VAE's sample size, 240x360)\n"
    "other:\n"
    "  --device I|NAME       Vulkan device\n"
    "  --progress bar|json|none   progress output (default bar); --quiet = none\n"
    "  --check               preflight only: check the options, files, model (configs, weight headers, tokenizer),\n"
    "                        LoRA, tiling and device memory, report every problem, run nothing (exit 0 = fine)\n"
    "  --from RUN.json       repeat a run from the run.json it wrote; options given next to it override its values\n"
    "Every run starts with that preflight. Outputs are staged and moved into DIR only when the run completes: a run\n"
    "that fails or is cancelled leaves the files of an earlier run in DIR as they were.\n"
    "Ctrl-C stops at the next stage or diffusion step, removes partial outputs and exits with 130.\n";

const std::set<std::string> kRunOptions = {"video", "depth", "depth-model", "depth-input-size", "trajectory", "out", "frames", "size", "resize",
                                           "intrinsics", "device", "model", "prompt", "negative-prompt", "preset",
                                           "steps", "strength", "inversion-steps", "k", "delta", "guidance", "seed",
                                           "dynamic-cfg", "preservation-scale",
                                           "cache-dir", "progress", "height", "width", "lora", "vae-tile",
                                           "depth-fit"};
const std::set<std::string> kRunFlags = {"metric-depth", "trim-depth", "points", "no-cache", "quiet", "vae-tiling"};


ProgressMode progress_mode(const Args& a) { return parse_progress_mode(a.str("progress"), a.has("quiet")); }

void print_stage_times(ProgressMode mode, const std::vector<StageTime>& stages, bool inversion_from_cache) {
  if (mode == ProgressMode::quiet) return;
  std::cerr << "stage times:";
  for (const auto& s : stages) std::cerr << " " << s.stage << " " << duration_text(s.seconds);
  std::cerr << (inversion_from_cache ? "  (inversion from the cache)" : "") << "\n";
}

int execute_run(const RunOptions& o, ProgressMode mode) {
  Progress progress(mode);
  RunReport r = run_pipeline(o, std::ref(progress), interrupted);
  progress.finish();
  print_stage_times(mode, r.stages, r.inversion_from_cache);
  std::cout << "wrote " << r.output_mp4.string() << "\n      " << r.render_mp4.string() << "\n      " << r.mask_mp4.string()
            << "\n      " << r.comparison_mp4.string() << "\n      " << r.run_json.string() << "\n";
  return 0;
}

namespace {

// An explicit value is used or refused, never swapped for the default (RunOptions' 0 = "the preset's").
double explicit_number(const Args& a, const std::string& name, double fallback, const std::function<bool(double)>& ok,
                       const std::string& range) {
  const double v = a.number(name, fallback);
  if (a.has(name) && !ok(v)) a.fail("--" + name + " must be " + range + ", got " + a.str(name) + " (leave it out for the default)");
  return v;
}

}  // namespace

RunOptions parse_run_options(const Args& a) {
  RunOptions o;
  o.render.video = a.required("video");
  parse_depth_source(a, o.render);
  o.render.out_dir = a.required("out");
  o.model = a.required("model");
  o.prompt = a.str("prompt");
  o.render.trajectory = a.str("trajectory", o.render.trajectory);
  o.render.frames = a.integer("frames", 49, 1, 100000);
  auto [h, w] = a.working_size({480, 720});
  o.render.height = h;
  o.render.width = w;
  std::string resize = a.str("resize", "crop");
  if (resize != "crop" && resize != "squash") a.fail("--resize must be crop or squash, got '" + resize + "'");
  o.render.squash = resize == "squash";
  o.render.metric_depth = a.has("metric-depth");
  o.render.trim_depth = a.has("trim-depth");
  o.render.depth_fit = a.str("depth-fit", "error");
  if (o.render.depth_fit != "error" && o.render.depth_fit != "stretch" && o.render.depth_fit != "crop")
    a.fail("--depth-fit must be error, stretch or crop, got '" + o.render.depth_fit + "'");
  o.render.hard_points = a.has("points");
  o.render.export_glb = false;
  o.render.device = a.str("device");
  if (a.has("intrinsics")) {
    auto k = a.numbers("intrinsics", 4);
    for (double v : k)
      if (!(v > 0 && std::isfinite(v)))
        a.fail("--intrinsics must be four numbers > 0 (fx,fy,cx,cy in pixels of the working size), got " + a.str("intrinsics") +
               " (leave it out for the default)");
    o.render.fx = k[0], o.render.fy = k[1], o.render.cx = k[2], o.render.cy = k[3];
  }
  o.negative_prompt = a.str("negative-prompt");
  o.preset = a.str("preset", "paper");
  o.steps = a.integer("steps", 0, 1, 1000);
  o.strength = explicit_number(a, "strength", 0, [](double v) { return v > 0 && v <= 1; }, "in (0, 1]");
  o.inversion_steps = a.integer("inversion-steps", 0, 1, 1000);
  o.k = explicit_number(a, "k", 10, [](double v) { return v > 0; }, "> 0");
  o.delta = explicit_number(a, "delta", 0, [](double v) { return v > 0; }, "> 0");
  o.guidance = explicit_number(a, "guidance", 6.0, [](double v) { return v >= 0; }, "≥ 0");
  if (a.has("dynamic-cfg")) {
    const std::string d = a.str("dynamic-cfg");
    if (d != "on" && d != "off") a.fail("--dynamic-cfg must be on or off, got '" + d + "'");
    o.dynamic_cfg = d == "on";
  }
  o.preservation_scale = explicit_number(a, "preservation-scale", 1.0, [](double v) { return v >= 0; }, "≥ 0");
  o.seed = uint64_t(a.integer("seed", 42, 0, 2147483647));
  o.cache_dir = a.str("cache-dir");
  o.use_cache = !a.has("no-cache");
  if (a.has("lora")) {
    const LoraSpec lora = parse_lora_spec(a.str("lora"));
    if (!std::isfinite(lora.scale)) a.fail("--lora: the scale must be a finite number, got " + a.str("lora"));
    o.lora = lora.file;
    o.lora_scale = lora.scale;
  }
  o.vae_tiling = a.has("vae-tiling") || a.has("vae-tile");
  if (a.has("vae-tile")) std::tie(o.vae_tile_height, o.vae_tile_width) = a.size("vae-tile", {0, 0});
  return o;
}

std::vector<std::string> with_recorded_run(const std::vector<std::string>& argv) {
  std::vector<std::string> own;
  std::string from;
  for (size_t i = 0; i < argv.size(); ++i) {
    if (argv[i] == "--from" && i + 1 < argv.size()) from = argv[++i];
    else if (argv[i].rfind("--from=", 0) == 0) from = argv[i].substr(7);
    else own.push_back(argv[i]);
  }
  if (from.empty()) return argv;
  std::vector<std::string> recorded = run_record_arguments(from);
  // The user's own --height/--width replace the recorded --size (the two forms do not mix).
  const bool own_dims = std::count(own.begin(), own.end(), "--height") + std::count(own.begin(), own.end(), "--width") > 0;
  std::vector<std::string> args;
  for (size_t i = 0; i < recorded.size(); ++i) {
    if (own_dims && recorded[i] == "--size") {
      ++i;
      continue;
    }
    args.push_back(recorded[i]);
  }
  args.insert(args.end(), own.begin(), own.end());  // later values win
  return args;
}

int run_run(const std::vector<std::string>& argv) {
  std::set<std::string> flags = kRunFlags;
  flags.insert("check");
  const std::vector<std::string> args = with_recorded_run(argv);
  Args a("run", args, kRunOptions, flags);
  if (a.help()) {
    std::cout << kRunHelp;
    return 0;
  }
  if (!a.has("prompt")) a.fail("--prompt is required (\"\" is allowed: no text conditioning)");
  const RunOptions o = parse_run_options(a);
  for (const auto& [text, option] : {std::pair{o.prompt, "--prompt"}, std::pair{o.negative_prompt, "--negative-prompt"}})
    if (auto w = prompt_truncation_warning(o.model, text, option)) std::cerr << "dvs run: " << *w << "\n";
  if (a.has("check")) {
    const PreflightReport r = preflight(o, JobKind::run);
    if (!r.ok()) throw Error(r.message());
    if (progress_mode(a) != ProgressMode::quiet)
      for (const auto& n : r.notes) std::cerr << "  " << n << "\n";
    // stdout stays JSON Lines under --progress json: the verdict goes to stderr there.
    (progress_mode(a) == ProgressMode::json ? std::cerr : std::cout)
        << "preflight: no problem found; dvs run with these options would start\n";
    return 0;
  }
  return execute_run(o, progress_mode(a));
}

int run_demo(const std::vector<std::string>& argv) {
  Args a("demo", argv, {"out", "device", "progress"}, {"quiet"});
  if (a.help()) {
    std::cout << "usage: dvs demo --out DIR [--device I|NAME] [--progress bar|json|none] [--quiet]\n\n"
                 "Generates a synthetic RGB-D clip (a box sliding in front of a wall) and a tiny random-weight model in\n"
                 "DIR, then runs the whole pipeline on them (render, encode, invert, SLM, K-RNR, sample, decode).\n"
                 "The output is noise-like (the model is random): the demo shows the machinery and its speed.\n";
    return 0;
  }
  std::filesystem::path dir = a.required("out");
  ProgressMode mode = progress_mode(a);
  if (mode != ProgressMode::quiet) std::cerr << "dvs demo: writing the synthetic scene and a tiny model to " << dir.string() << "\n";
  RunOptions o = prepare_demo(dir);
  o.render.device = a.str("device");
  return execute_run(o, mode);
}

}  // namespace dvs::cli
