#include "pipeline/preflight.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <set>

#include "io/public_call.hpp"
#include "diffusion/schedule.hpp"
#include "dvs/depth_estimate.hpp"
#include "dvs/error.hpp"
#include "models/vda/vda_model.hpp"
#include "geometry/trajectory.hpp"
#include "io/lora_file.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "io/depth.hpp"
#include "io/depth_images.hpp"
#include "io/video.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "pipeline/cache_layout.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/depth_source.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/memory_plan.hpp"
#include "io/option_names.hpp"
#include "pipeline/output_path.hpp"
#include "pipeline/prompt_cut.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/settings.hpp"
#include "vk/context.hpp"
#include "vk/device_info.hpp"

namespace dvs {
namespace {

std::string hw(int64_t h, int64_t w) { return std::to_string(h) + "x" + std::to_string(w); }

// A depth source's shape as the render stage will read it: an array's [N,H,W] (the file is read), a folder's image
// count (its frame size unknown here), a grayscale video's container count and frame size; 0 where unknown.
struct DepthShape {
  int64_t frames = 0, height = 0, width = 0;
};
DepthShape depth_shape(const std::filesystem::path& spec) {
  const auto path = split_npz_key(spec).first;
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return {int64_t(depth_image_files(path).size())};
  std::string ext = path.extension().string();
  for (auto& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  if (ext == ".npy" || ext == ".npz") {
    const Shape s = read_depth_array(spec).shape;
    return {s.at(0), s.at(1), s.at(2)};
  }
  VideoReadOptions vo;
  vo.max_frames = 1;
  vo.height = 8, vo.width = 8;
  VideoInfo vi;
  read_video(path, vo, &vi);
  return {vi.frames_in_file, vi.height, vi.width};
}

class Checker {
 public:
  explicit Checker(PreflightReport& r) : r_(r) {}
  // Runs `f`; a dvs::Error it throws becomes a problem (prefixed with `what` when given).
  bool attempt(const std::string& what, const std::function<void()>& f) {
    try {
      f();
      return true;
    } catch (const Error& e) {
      problem(what.empty() ? e.what() : what + ": " + e.what());
      return false;
    } catch (const std::exception& e) {
      problem((what.empty() ? std::string() : what + ": ") + e.what());
      return false;
    }
  }
  void problem(const std::string& p) { r_.problems.push_back(p); }
  void note(const std::string& n) { r_.notes.push_back(n); }

 private:
  PreflightReport& r_;
};

// The camera path: presets and files are resolved now (the radius only scales dolly/truck moves).
void check_trajectory(const RunOptions& o, Checker& c) {
  const RenderJob& j = o.render;
  c.attempt(option_name("RenderJob::trajectory") + " " + j.trajectory, [&] {
    for (const auto& w : geometry::load_trajectory(j.trajectory, std::max(1, j.frames), 1.0).warnings) c.note("warning: " + w);
  });
}

// The video's frames as the container says (for the depth estimate's plan); nothing when it cannot be read.
struct VideoFacts {
  int64_t frames = 0, height = 0, width = 0;
};

std::optional<VideoFacts> check_inputs(const RunOptions& o, Checker& c, const PreflightScope& scope) {
  const RenderJob& j = o.render;
  const std::string size = option_name("RenderJob::height/width"), frames_option = option_name("RenderJob::frames");
  if (j.height <= 0 || j.width <= 0 || j.height % 8 || j.width % 8)
    c.problem(size + " " + hw(j.height, j.width) + ": height and width must be positive multiples of 8 (the VAE works on " +
              "8x8 pixel cells), e.g. " + hw(std::max(8, j.height / 8 * 8), std::max(8, j.width / 8 * 8)));
  if (!std::isfinite(j.fx) || !std::isfinite(j.fy) || !std::isfinite(j.cx) || !std::isfinite(j.cy) ||
      ((j.fx != 0 || j.fy != 0 || j.cx != 0 || j.cy != 0) && !(j.fx > 0 && j.fy > 0 && j.cx > 0 && j.cy > 0)))
    c.problem(option_name("RenderJob::fx/fy/cx/cy") + ": fx, fy, cx, cy must all be > 0 (pixels of the working size), "
              "or all 0 for the default");
  c.attempt("", [&] { parse_depth_fit(j.depth_fit); });
  if (!scope.input_files) {  // a clip in memory: its views are checked by the run itself
    if (scope.trajectory) check_trajectory(o, c);
    return std::nullopt;
  }
  // The video: opened and its --frames decoded small (one frame when all are used), which finds a file that stops
  // before --frames; the container's frame count covers the rest.
  std::optional<int64_t> video_frames;
  std::optional<VideoFacts> facts;
  if (!std::filesystem::is_regular_file(j.video)) {
    c.problem(j.video.string() + ": no such video file (give " + option_name("RenderJob::video") + ")");
  } else {
    c.attempt("", [&] {
      VideoReadOptions vo;
      vo.max_frames = j.frames > 0 ? j.frames : 1;
      vo.height = 8, vo.width = 8;
      VideoInfo vi;
      read_video(j.video, vo, &vi);
      if (vi.frames_in_file > 0) video_frames = vi.frames_in_file;
      facts = VideoFacts{vi.frames_in_file, vi.height, vi.width};
      if (vi.frames_in_file > 0 && j.frames > vi.frames_in_file) {
        const int fit = (vi.frames_in_file - 1) / 4 * 4 + 1;
        c.problem(j.video.string() + ": holds " + std::to_string(vi.frames_in_file) + " frames, fewer than " + frames_option +
                  " " + std::to_string(j.frames) + "; use " + frames_option + " " + std::to_string(fit) +
                  " (the largest 4k+1 it has)");
      }
      c.note("video " + j.video.string() + ": " + std::to_string(vi.frames_in_file) + " frames of " + hw(vi.height, vi.width));
    });
  }
  if (!j.depth_model.empty()) {
    if (!std::filesystem::is_regular_file(j.depth_model))
      c.problem(j.depth_model.string() + ": no such depth model (give " + option_name("RenderJob::depth_model") +
                " video_depth_anything_vits.pth)");
    else
      c.attempt(option_name("RenderJob::depth_model") + " " + j.depth_model.string(), [&] {
        const VdaConfig v = VdaModel::inspect(j.depth_model);
        c.note("depth model " + j.depth_model.string() + ": Video-Depth-Anything " + v.name + (v.metric ? " (metric)" : ""));
      });
    if (j.depth_input_size < 14 || j.depth_input_size > 4096)
      c.problem(option_name("RenderJob::depth_input_size") + " must be in [14, 4096], got " + std::to_string(j.depth_input_size));
    // The estimate is kept in the depth cache and read from there by the render (even with --no-cache, which
    // only skips reading an earlier entry): a folder it cannot write fails the job, so it is said now.
    if (auto old = old_cache_layout(o.cache_dir)) c.problem(option_name("RenderJob::depth_model") + ": " + *old);
    const InversionCache depth_cache(o.cache_dir, "depth");
    if (auto p = folder_write_problem(depth_cache.dir(), "point " + option_name("RunOptions::cache_dir") +
                                                             " (or DVS_CACHE_DIR) at a writable folder"))
      c.problem(option_name("RenderJob::depth_model") + ": the estimate is kept in the depth cache, which cannot be written: " + *p);
  } else if (!depth_source_exists(j.depth)) {
    c.problem(j.depth.string() + ": no such depth file or folder (give " + option_name("RenderJob::depth") + ", or " +
              option_name("RenderJob::depth_model") + " to estimate it)");
  } else if (video_frames) {
    // The render stage's frame rule (render_job.cpp): depth for every frame the job uses; more only when it is
    // the whole clip's (cut with --frames) or --trim-depth says so.
    c.attempt(option_name("RenderJob::depth") + " " + j.depth.string(), [&] {
      const DepthShape shape = depth_shape(j.depth);
      // Depth of another aspect ratio, or far too small, for the video (the render stage's own rule, from the
      // file's shape): said now, not after the decode.
      if (shape.height > 0 && facts && facts->height > 0 && j.height > 0 && j.width > 0) {
        const VideoFrameGeometry g{int(facts->height), int(facts->width), j.height, j.width,
                                   j.squash ? ResizeMode::squash : ResizeMode::crop};
        c.attempt("", [&] { depth_region_for_video(shape.height, shape.width, g, parse_depth_fit(j.depth_fit), j.depth.string()); });
      }
      if (shape.frames <= 0) return;
      const int64_t n = shape.frames;
      const int64_t used = j.frames > 0 ? std::min<int64_t>(j.frames, *video_frames) : *video_frames;
      const std::string frames = j.frames > 0 ? frames_option + " " + std::to_string(j.frames) : "the video's " + std::to_string(used) + " frames";
      if (n < used) {
        const int64_t fit = (n - 1) / 4 * 4 + 1;
        c.problem(j.depth.string() + ": holds " + std::to_string(n) + " depth frames, fewer than " + frames +
                  "; give depth for every frame, or " + frames_option + " " + std::to_string(std::max<int64_t>(fit, 1)) +
                  " (the largest 4k+1 it covers)");
      } else if (n > used && !j.trim_depth && n != *video_frames) {
        c.problem(j.depth.string() + ": holds " + std::to_string(n) + " depth frames but the job uses " + frames +
                  " (and the video holds " + std::to_string(*video_frames) + "): " + option_name("RenderJob::trim_depth") + " uses its first " +
                  std::to_string(used));
      }
    });
  }
  if (scope.trajectory) check_trajectory(o, c);
  // The output folder: an existing folder we may write into, or creatable below one.
  if (auto p = folder_write_problem(j.out_dir, "give another " + option_name("RenderJob::out_dir"))) c.problem(*p);
  return facts;
}

struct ModelFacts {
  std::optional<models::CogVideoXTransformerConfig> transformer;
  std::optional<models::VaeConfig> vae;
  std::optional<models::T5EncoderConfig> t5;
  nlohmann::json transformer_json, vae_json, t5_json;
};

// One component: its config parses, and its safetensors headers hold every tensor the config implies, with the
// right shape and a dtype the engine reads.
void check_component(const std::filesystem::path& model, const std::string& name, Checker& c, nlohmann::json& config_out,
                     const std::function<Schema(const nlohmann::json&, std::string_view)>& schema_of,
                     const std::function<void(const nlohmann::json&, std::string_view)>& parse) {
  const auto dir = model / name;
  const std::string origin = (dir / "config.json").string();
  nlohmann::json cfg;
  if (!c.attempt("", [&] { cfg = read_json_file(dir / "config.json", "the model folder must hold " + name + "/config.json"); }))
    return;
  if (!c.attempt("", [&] { parse(cfg, origin); })) return;
  config_out = cfg;
  Schema schema;
  if (!c.attempt("", [&] { schema = schema_of(cfg, origin); })) return;
  std::optional<WeightSet> ws;
  if (!c.attempt(dir.string(), [&] { ws.emplace(WeightSet::open_dir(dir)); })) return;
  std::vector<std::string> issues;
  for (const SchemaIssue& i : check_schema(schema, *ws))
    if (i.kind != SchemaIssue::Kind::unexpected) issues.push_back(i.message());
  for (const auto& [tensor, ref] : ws->entries())
    if (!ref.info->dtype)
      issues.push_back("tensor '" + tensor + "': dtype " + ref.info->dtype_name + " cannot be used (F32, F16 or BF16)");
  if (!issues.empty()) {
    std::string text = ws->source().string() + ": " + std::to_string(issues.size()) + " weight" +
                       (issues.size() == 1 ? "" : "s") + " missing or mis-shaped for " + origin + " (";
    for (size_t i = 0; i < std::min<size_t>(issues.size(), 5); ++i) text += (i ? "; " : "") + issues[i];
    if (issues.size() > 5) text += "; and " + std::to_string(issues.size() - 5) + " more";
    c.problem(text + "); the weights do not belong to this config — re-download or re-convert the component");
  }
}

ModelFacts check_model(const RunOptions& o, Checker& c) {
  ModelFacts m;
  if (!std::filesystem::is_directory(o.model)) {
    c.problem(o.model.string() + ": no such model folder (give " + option_name("RunOptions::model") +
              " a folder laid out like THUDM/CogVideoX-5b-I2V)");
    return m;
  }
  c.attempt("", [&] { ModelFolder::open(o.model); });
  check_component(o.model, "transformer", c, m.transformer_json,
                  [](const nlohmann::json& j, std::string_view s) { return cogvideox_transformer_schema(j, s); },
                  [&](const nlohmann::json& j, std::string_view s) { m.transformer = models::CogVideoXTransformerConfig::from_json(j, s); });
  check_component(o.model, "vae", c, m.vae_json,
                  [](const nlohmann::json& j, std::string_view s) { return cogvideox_vae_schema(j, s); },
                  [&](const nlohmann::json& j, std::string_view) { m.vae = models::VaeConfig::from_json(j); });
  check_component(o.model, "text_encoder", c, m.t5_json,
                  [](const nlohmann::json& j, std::string_view s) { return t5_encoder_schema(j, s); },
                  [&](const nlohmann::json& j, std::string_view s) { m.t5 = models::T5EncoderConfig::from_json(j, s); });
  c.attempt("", [&] { T5Tokenizer::load(o.model); });
  c.attempt("", [&] { max_text_seq_length(o.model); });
  return m;
}

// The prompts the model cuts, as warnings among the notes (a tokenizer that cannot be read is check_model's problem).
void note_prompt_cuts(const RunOptions& o, Checker& c) {
  try {
    for (const std::string& w : prompt_cut_warnings(o, T5Tokenizer::load(o.model), max_text_seq_length(o.model)))
      c.note("warning: " + w);
  } catch (const std::exception&) {
  }
}

// The size, frames and channels against what the configs fix.
void check_model_fit(const RunOptions& o, const ModelFacts& m, Checker& c) {
  if (!m.transformer || !m.vae) return;
  const auto& t = *m.transformer;
  const auto& v = *m.vae;
  const int64_t r = v.spatial_ratio(), cell = r * t.patch_size;
  const int H = o.render.height, W = o.render.width;
  const std::string size = option_name("RenderJob::height/width");
  if (t.learned_pos && (H != t.sample_height * r || W != t.sample_width * r)) {
    c.problem(size + " " + hw(H, W) + ": this model's learned positional table needs " + size + " " +
              hw(t.sample_height * r, t.sample_width * r) + " (any 4k+1 " + option_name("RenderJob::frames") +
              "; diffusers rejects other sizes for it)");
  } else if (H > 0 && W > 0 && (H % cell || W % cell)) {
    c.problem(size + " " + hw(H, W) + ": the latent (" + hw(H / r, W / r) + ") must be a multiple of the transformer's patch " +
              std::to_string(t.patch_size) + ", so height and width must be multiples of " + std::to_string(cell) +
              ", e.g. " + size + " " + hw(std::max(cell, H / cell * cell), std::max(cell, W / cell * cell)));
  }
  if (v.latent_channels * 2 != t.in_channels || v.latent_channels != t.out_channels)
    c.problem(o.model.string() + ": the VAE's latent_channels (" + std::to_string(v.latent_channels) +
              ") do not match the transformer's in_channels/out_channels (" + std::to_string(t.in_channels) + "/" +
              std::to_string(t.out_channels) + "; CogVideoX I2V needs 2x and 1x): the components come from different models");
  if (m.t5 && m.t5->d_model != t.text_embed_dim)
    c.problem(o.model.string() + ": the text encoder's d_model (" + std::to_string(m.t5->d_model) +
              ") differs from the transformer's text_embed_dim (" + std::to_string(t.text_embed_dim) +
              "): the components come from different models");
  if (o.vae_tiling)
    c.attempt("", [&] {
      check_tiles_join(v, *vae_tiling(o));  // the run's own check
    });
}

void check_lora(const RunOptions& o, const ModelFacts& m, Checker& c) {
  if (o.lora.empty()) return;
  if (!std::filesystem::is_regular_file(o.lora)) {
    c.problem(o.lora.string() + ": no such LoRA file (give " + option_name("RunOptions::lora") + " a .safetensors adapter)");
    return;
  }
  if (!std::isfinite(o.lora_scale)) c.problem(option_name("RunOptions::lora_scale") + ": the scale must be a finite number");
  c.attempt(option_name("RunOptions::lora") + " " + o.lora.string(), [&] {
    const auto adapters = read_lora_file(o.lora, o.lora_scale);
    if (!m.transformer) return;
    const int64_t D = m.transformer->dim();
    std::set<std::string> known;
    for (int64_t i = 0; i < m.transformer->num_layers; ++i)
      for (const char* p : {"attn1.to_q", "attn1.to_k", "attn1.to_v", "attn1.to_out.0"})
        known.insert("transformer_blocks." + std::to_string(i) + "." + p);
    for (const auto& [name, ad] : adapters) {
      if (!known.count(name))
        throw Error("module '" + name + "' is not an attention projection of this transformer (supported: " +
                    "transformer_blocks.<i>.attn1.{to_q,to_k,to_v,to_out.0}, i < " + std::to_string(m.transformer->num_layers) +
                    "): the adapter was made for another model");
      if (ad.a.shape != Shape{ad.rank(), D} || ad.b.shape != Shape{D, ad.rank()})
        throw Error("module '" + name + "' has A [" + shape_str(ad.a.shape) + "] and B [" + shape_str(ad.b.shape) +
                    "], this transformer needs A [rank, " + std::to_string(D) + "] and B [" + std::to_string(D) +
                    ", rank]: the adapter was made for another model");
    }
  });
}

// The device a job names (--device), listed once per process: a batch preflights every job.
const vk::DeviceCaps* chosen_device(const std::string& device, Checker& c) {
  static std::optional<std::vector<vk::DeviceCaps>> listed;
  if (!listed && !c.attempt("", [&] { listed = vk::list_devices(); })) return nullptr;
  uint32_t index = 0;
  if (!c.attempt(option_name("RenderJob::device"), [&] { index = vk::select_device(*listed, device); })) return nullptr;
  return &listed->at(index);
}

// --depth-model: the estimate the run will make (none when the depth cache holds it), planned as `dvs plan
// --depth-model` plans it: the checkpoint's architecture, the network input, the frames at the size the
// estimate reads them (the video's, scaled down to DepthJob::max_res as read_video_rgb8 does).
void plan_depth_stage(const RunOptions& o, const std::optional<VideoFacts>& video, pipeline::PlanRequest& req) {
  const RenderJob& j = o.render;
  if (j.depth_model.empty() || !video || video->height <= 0 || !std::filesystem::is_regular_file(j.depth_model)) return;
  const DepthJob d = depth_job_for(j, o.cache_dir, !o.use_cache);
  if (o.use_cache && depth_cache_has(d)) return;  // read from the cache: nothing is estimated
  try {
    req.depth_model = VdaModel::inspect(j.depth_model);
  } catch (const Error&) {
    return;  // check_inputs has named what is wrong with the checkpoint
  }
  req.depth_input_size = j.depth_input_size;
  int64_t h = video->height, w = video->width;
  if (d.max_res > 0 && std::max(h, w) > d.max_res) {
    const double s = double(d.max_res) / double(std::max(h, w));
    h = int64_t(std::nearbyint(double(video->height) * s)), w = int64_t(std::nearbyint(double(video->width) * s));
  }
  req.depth_frame_height = h, req.depth_frame_width = w;
}

// Device memory and device limits as the planner sees them (dvs plan --device): the whole run's peak against the
// chosen device's memory budget (vk/memory_budget: host RAM available on a CPU device, the device-local heap's
// budget or size on a GPU; the figure the Allocator enforces and `dvs info` prints), and every allocation of
// every stage against maxMemoryAllocationSize (DVS_LIMITS included), with the VAE tiling the run was given.
// The plan's VAE figures are the ones the VAE's calls check before any work (CogVideoXVae::*_footprint): what
// passes here runs, what fails here would fail there.
void check_memory(const RunOptions& o, const ModelFacts& m, const std::optional<VideoFacts>& video, Checker& c,
                  const vk::DeviceCaps* device) {
  if (!m.transformer || !m.vae || !m.t5 || (o.render.frames - 1) % 4 != 0) return;
  const int64_t r = m.vae->spatial_ratio();
  if (m.transformer->learned_pos && (o.render.height != m.transformer->sample_height * r ||
                                     o.render.width != m.transformer->sample_width * r))
    return;  // check_model_fit names the size this model takes; no size of its own runs
  if (const auto t = vae_tiling(o)) {  // tiles that do not join have no plan (the tiling check names them)
    try {
      check_tiles_join(*m.vae, *t);
    } catch (const Error&) {
      return;
    }
  }
  const vk::DeviceCaps* chosen = device ? device : chosen_device(o.render.device, c);
  if (!chosen) return;
  const vk::DeviceCaps& dev = *chosen;
  const std::string tile = option_name("RunOptions::vae_tile_height/width");
  c.attempt("memory plan", [&] {
    const pipeline::PlanModel pm = pipeline::plan_model_from_folder(o.model);
    pipeline::PlanRequest req = run_plan_request(o, dev);  // the request an out-of-memory error's advice plans too
    plan_depth_stage(o, video, req);
    const std::optional<models::VaeTiling> given = req.tiling;
    const pipeline::MemoryPlan plan = pipeline::plan_memory(pm, req);
    c.note("memory plan: " + pipeline::format_plan_bytes(plan.tilings[given ? 1 : 0].run_peak) + " at the peak" +
           (given ? " with " + tile + " " : std::string(" untiled")) +
           (given ? hw(given->tile_sample_min_height, given->tile_sample_min_width) : std::string()) +
           "; device memory for dvs: " + dev.memory_budget.describe());
    std::string weights = "block weights (--weights " + o.weights + "):";
    for (const auto& st : plan.streams)
      weights += std::string(" ") + (st.component == "transformer" ? "transformer" : "T5") + " " +
                 (st.streamed ? "streamed (" + std::to_string(st.slots) + " slots of " +
                                    pipeline::format_plan_bytes(st.slot_bytes) + ", " +
                                    pipeline::format_plan_bytes(st.host_bytes) + " uploaded " + st.calls + ")"
                              : std::string("resident")) +
                 (&st == &plan.streams.back() ? "" : ",");
    c.note(weights);
    const pipeline::TilingOption& mine = plan.tilings[given ? 1 : 0];  // given: [untiled, the given tiling]
    if (mine.blocker.empty()) return;
    const std::string what = given ? tile + " " + hw(given->tile_sample_min_height, given->tile_sample_min_width) : "untiled";
    // What would run: the plan's own offers (a second plan when the run named its tiling).
    std::optional<pipeline::MemoryPlan> offers_storage;
    if (given) {
      req.tiling.reset();
      offers_storage = pipeline::plan_memory(pm, req);
    }
    const pipeline::MemoryPlan& offers = given ? *offers_storage : plan;
    if (mine.fixed || offers.chosen < 0) {
      c.problem("device memory on " + dev.name + ": " + (offers.notes.empty() ? "nothing runs: " + mine.blocker : offers.notes.back()));
    } else if (offers.chosen == 0) {
      c.problem("device memory: " + what + ", " + mine.blocker + "; run without " + option_name("RunOptions::vae_tiling") +
                " (untiled fits)");
    } else {
      const auto& t = offers.tilings[size_t(offers.chosen)].tiling;
      c.problem("device memory: " + what + ", " + mine.blocker + "; " + (given ? "use" : "add") + " " + tile + " " +
                hw(t.tile_sample_min_height, t.tile_sample_min_width) + " (fits; dvs plan --device shows the plan)");
    }
  });
}

}  // namespace

std::string PreflightReport::message() const {
  std::string m = "preflight found " + std::to_string(problems.size()) + " problem" + (problems.size() == 1 ? "" : "s") +
                  "; nothing was run:";
  for (const auto& p : problems) m += "\n  - " + p;
  return m;
}

PreflightReport preflight(const RunOptions& o, JobKind kind) {
  return public_call("dvs::preflight", [&] { return preflight(o, kind, PreflightScope{}); });
}

PreflightReport preflight(const RunOptions& o, JobKind kind, const PreflightScope& scope) {
  PreflightReport r;
  Checker c(r);
  std::optional<Settings> st;
  c.attempt("", [&] { st = resolve(o); });
  if (kind == JobKind::run && st) {
    const bool dynamic_cfg = o.dynamic_cfg.value_or(st->official);
    if (dynamic_cfg && !(o.preservation_scale >= 0 && std::isfinite(o.preservation_scale)))
      c.problem(option_name("RunOptions::preservation_scale") + " must be a finite number ≥ 0, got " +
                std::to_string(o.preservation_scale));
  }
  const std::optional<VideoFacts> video = check_inputs(o, c, scope);
  if (o.use_cache && o.render.depth_model.empty())  // (with --depth-model check_inputs has said it)
    if (auto old = old_cache_layout(o.cache_dir)) c.problem(*old);
  const ModelFacts m = check_model(o, c);
  if (kind == JobKind::run) note_prompt_cuts(o, c);
  if (std::filesystem::is_directory(o.model) && st)
    c.attempt("", [&] {
      diffusion::CogVideoXSchedule schedule(diffusion::load_scheduler_config(o.model));
      const diffusion::SamplingPlan plan = schedule.plan(st->steps, st->strength);
      if (kind == JobKind::run && plan.num_steps() < 1)
        throw Error(option_name("RunOptions::steps") + " " + std::to_string(st->steps) + " at " +
                    option_name("RunOptions::strength") + " " + std::to_string(st->strength) +
                    " leaves no sampling step; raise either");
    });
  check_model_fit(o, m, c);
  check_lora(o, m, c);
  check_memory(o, m, video, c, scope.device);
  return r;
}

PreflightReport preflight_render(const RenderJob& job) {
  return public_call("dvs::preflight_render", [&]() -> PreflightReport {
    PreflightReport r;
    Checker c(r);
    RunOptions o;
    o.render = job;
    o.cache_dir = job.depth_cache_dir;  // where render's --depth-model keeps its estimate
    check_inputs(o, c, PreflightScope{});
    // The render's buffers against the device's limits (the same figures the renderer chunks with).
    if (const vk::DeviceCaps* dev = chosen_device(job.device, c))
      if (auto p = render_limits_problem(job, *dev)) c.problem(*p);
    return r;
  });
}

void require_preflight(const RunOptions& o, JobKind kind, const PreflightScope& scope) {
  const PreflightReport r = preflight(o, kind, scope);
  if (!r.ok()) throw Error(r.message());
}

}  // namespace dvs
