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
#include "dvs/lora.hpp"
#include "dvs/preflight.hpp"
#include "dvs/run_record.hpp"
#include "dvs/usage_error.hpp"
#include "dvs/duration_text.hpp"
#include "interrupt.hpp"
#include "depth_args.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "run_command.hpp"

namespace dvs::cli {

namespace {

const CommandHelp kRunHelp{
    "dvs run --video V (--depth D | --depth-model FILE.pth) --model DIR --prompt TEXT --out DIR [options]",
    "Re-renders V along a new camera path: renders the input with its depth, VAE-encodes the render, inverts it\n"
    "with the transformer, fills occluded latents (SLM), initialises the noise (adaptive K-RNR) and samples the\n"
    "new view. Writes DIR/output.mp4, render.mp4, mask.mp4, comparison.mp4 (input | render | output) and run.json.\n"
    "Its inputs are dvs render's (the same options).\n",
    "Every run starts with the preflight of --check. Outputs are staged and moved into DIR only when the run\n"
    "completes: a run that fails or is cancelled leaves the files of an earlier run in DIR as they were.\n"
    "Ctrl-C stops at the next stage or diffusion step, removes partial outputs and exits with 130.\n"};

const OptionGroup kReplay{
    "replay",
    {{"from", "RUN.json",
      "repeat a run from the run.json it wrote, into the --out given next to it (required: the recorded folder holds the "
      "run being repeated); other options given next to it override its values"}}};

}  // namespace

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
  if ((o.render.frames - 1) % 4 != 0)
    a.fail("--frames must be 4k+1 (1, 5, 9, ..., 49): the VAE compresses time by 4 after the first frame, got " +
           std::to_string(o.render.frames));
  std::tie(o.render.height, o.render.width) = a.working_size({480, 720});
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
  if (o.preset != "paper" && o.preset != "official") a.fail("--preset must be paper or official, got '" + o.preset + "'");
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
    try {
      const LoraArgument lora = parse_lora_argument(a.str("lora"));
      o.lora = lora.file;
      o.lora_scale = lora.scale;
    } catch (const UsageError& e) {
      a.fail(e.what());
    }
  }
  o.weights = a.str("weights", "auto");
  if (o.weights != "auto" && o.weights != "resident" && o.weights != "stream")
    a.fail("--weights must be resident, stream or auto, got '" + o.weights + "'");
  o.vae_tiling = a.has("vae-tiling") || a.has("vae-tile");
  if (a.has("vae-tile")) {
    std::tie(o.vae_tile_height, o.vae_tile_width) = a.size("vae-tile", {0, 0});
    if (o.vae_tile_height % 8 || o.vae_tile_width % 8)
      a.fail("--vae-tile must be multiples of 8, got " + a.str("vae-tile") + "; e.g. " +
             std::to_string(std::max(8, o.vae_tile_height / 8 * 8)) + "x" + std::to_string(std::max(8, o.vae_tile_width / 8 * 8)));
  }
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
  // The recorded --out holds the run being repeated: writing there would replace it, which a replay must not do
  // unasked. --out DIR (that folder included, on purpose) says where the repeat goes.
  const bool own_out = std::any_of(own.begin(), own.end(), [](const std::string& s) { return s == "--out" || s.rfind("--out=", 0) == 0; });
  if (!own_out && std::find(own.begin(), own.end(), "--help") == own.end() && std::find(own.begin(), own.end(), "-h") == own.end()) {
    const auto out = std::find(recorded.begin(), recorded.end(), "--out");
    const std::string recorded_out = out != recorded.end() && out + 1 != recorded.end() ? *(out + 1) : "its folder";
    throw UsageError("--from " + from + " without --out would write into " + recorded_out +
                     ", replacing the run it repeats; give --out NEW_DIR (or --out " + recorded_out + " to replace it)");
  }
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
  std::vector<OptionGroup> groups = run_option_groups();
  groups.push_back(kCheckOnly);
  groups.push_back(kReplay);
  Args a("run", kRunHelp, groups);
  a.parse(with_recorded_run(argv));
  if (a.help()) return 0;
  if (!a.has("prompt")) a.fail("--prompt is required (\"\" is allowed: no text conditioning)");
  const RunOptions o = parse_run_options(a);
  if (a.has("check")) {
    const PreflightReport r = preflight(o, JobKind::run);
    if (!r.ok()) throw Error(r.message());
    for (const auto& n : r.notes)  // warnings whatever --progress says
      if (progress_mode(a) != ProgressMode::quiet || n.rfind("warning: ", 0) == 0) std::cerr << "  " << n << "\n";
    // stdout stays JSON Lines under --progress json: the verdict goes to stderr there.
    (progress_mode(a) == ProgressMode::json ? std::cerr : std::cout)
        << "preflight: no problem found; dvs run with these options would start\n";
    return 0;
  }
  return execute_run(o, progress_mode(a));
}

int run_demo(const std::vector<std::string>& argv) {
  Args a("demo",
         {"dvs demo --out DIR [--device I|NAME] [--progress bar|json|none | --quiet]",
          "Generates a synthetic RGB-D clip (a box sliding in front of a wall) and a tiny random-weight model in\n"
          "DIR, then runs the whole pipeline on them (render, encode, invert, SLM, K-RNR, sample, decode).\n"
          "The output is noise-like (the model is random): the demo shows the machinery and its speed.\n",
          ""},
         {kOutFolder, kDevice, kProgressOutput});
  a.parse(argv);
  if (a.help()) return 0;
  std::filesystem::path dir = a.required("out");
  ProgressMode mode = progress_mode(a);
  if (mode != ProgressMode::quiet) std::cerr << "dvs demo: writing the synthetic scene and a tiny model to " << dir.string() << "\n";
  RunOptions o = prepare_demo(dir);
  o.render.device = a.str("device");
  return execute_run(o, mode);
}

}  // namespace dvs::cli
