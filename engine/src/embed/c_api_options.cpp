// dvs/dvs.h's option structs: their defaults (taken from the C++ structs' own, so the two never drift apart), how a
// struct is read through its struct_size, and the conversion to dvs::RenderJob / dvs::RunOptions.
//
// Why struct_size and not setters: plain structs are what C, C# (Unity), GDExtension and ctypes declare most easily,
// and struct_size lets the struct grow at its end without breaking a program built against an older dvs.h (its
// struct is shorter: the missing fields take their defaults) or a library older than the program's header (the
// fields it does not know must be zero). A struct inside another is held by pointer so that each can grow.
#include "embed/c_api_options.hpp"

#include <algorithm>
#include <cstddef>
#include <cstring>

#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"

namespace dvs::capi {
namespace {

std::string text(const char* s) { return s ? s : ""; }

// The sizes of the first dvs.h whose structs had struct_size: anything smaller was never filled by *_default.
constexpr size_t kFirstRenderOptionsSize = offsetof(dvs_render_options, depth_cache) + sizeof(int32_t);
constexpr size_t kFirstPipelineOptionsSize = offsetof(dvs_pipeline_options, vae_tile_width) + sizeof(int32_t);

}  // namespace

RenderJob render_job(const dvs_render_options& given, const char* call) {
  const dvs_render_options o =
      read_filled(given, dvs_render_options_default, kFirstRenderOptionsSize, "dvs_render_options", call);
  RenderJob j;
  j.video = text(o.video);
  j.depth = text(o.depth);
  j.depth_model = text(o.depth_model);
  j.out_dir = text(o.out_dir);
  if (o.trajectory) j.trajectory = o.trajectory;
  j.device = text(o.device);
  j.frames = o.frames;
  j.height = o.height, j.width = o.width;
  j.metric_depth = o.metric_depth != 0;
  j.hard_points = o.hard_points != 0;
  j.depth_input_size = o.depth_input_size;
  j.squash = o.squash != 0;
  j.trim_depth = o.trim_depth != 0;
  if (o.depth_fit) j.depth_fit = o.depth_fit;
  j.fx = o.fx, j.fy = o.fy, j.cx = o.cx, j.cy = o.cy;
  j.export_glb = o.export_glb != 0;
  j.save_npy = o.save_npy != 0;
  j.depth_cache_dir = text(o.depth_cache_dir);
  j.depth_cache = o.depth_cache != 0;
  return j;
}

RunOptions run_options(const dvs_pipeline_options& given, const char* call) {
  const dvs_pipeline_options o =
      read_filled(given, dvs_pipeline_options_default, kFirstPipelineOptionsSize, "dvs_pipeline_options", call);
  RunOptions r;
  if (o.render) r.render = render_job(*o.render, call);
  r.model = text(o.model);
  r.prompt = text(o.prompt);
  r.negative_prompt = text(o.negative_prompt);
  if (o.preset) r.preset = o.preset;
  r.cache_dir = text(o.cache_dir);
  r.lora = text(o.lora);
  r.steps = o.steps, r.inversion_steps = o.inversion_steps;
  r.strength = o.strength, r.k = o.k, r.delta = o.delta, r.guidance = o.guidance;
  r.lora_scale = o.lora_scale;
  r.seed = o.seed;
  r.use_cache = o.use_cache != 0;
  if (o.dynamic_cfg != -1 && o.dynamic_cfg != 0 && o.dynamic_cfg != 1)
    throw UsageError(std::string(call) + ": dvs_pipeline_options.dynamic_cfg must be -1 (the preset's choice), 0 (off) "
                     "or 1 (on), got " + std::to_string(o.dynamic_cfg));
  if (o.dynamic_cfg != -1) r.dynamic_cfg = o.dynamic_cfg == 1;
  r.preservation_scale = o.preservation_scale;
  r.vae_tiling = o.vae_tiling != 0;
  r.vae_tile_height = o.vae_tile_height, r.vae_tile_width = o.vae_tile_width;
  if (o.weights) r.weights = o.weights;  // checked by the run (settings.cpp), naming dvs_pipeline_options.weights
  return r;
}

std::string c_option_names(std::string message) {
  static const std::pair<const char*, const char*> kNames[] = {
      {"RunOptions::render.", "dvs_pipeline_options.render->"},
      {"RunOptions::", "dvs_pipeline_options."},
      {"RenderJob::", "dvs_render_options."},
      {"MemoryPlanRequest::", "dvs_plan_request."},
      {"dvs::enable_video_files()", "dvs_enable_video_files() (dvs/dvs_video.h)"},
  };
  for (const auto& [cpp, c] : kNames)
    for (size_t at = message.find(cpp); at != std::string::npos; at = message.find(cpp, at + std::strlen(c)))
      message.replace(at, std::strlen(cpp), c);
  return message;
}

dvs_status start_job(dvs_job** out, const char* call, const char* kind, const std::function<Job()>& begin) {
  return guarded(DVS_ERROR_FILE, [&] {
    require(out, call, "out");
    *out = nullptr;
    auto handle = std::unique_ptr<dvs_job>(new dvs_job{begin(), kind});
    *out = handle.release();
  });
}

}  // namespace dvs::capi

extern "C" {

dvs_status dvs_render_options_default(dvs_render_options* out) {
  using namespace dvs::capi;
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    require(out, "dvs_render_options_default", "out");
    static const dvs::RenderJob d;
    static const std::string trajectory = d.trajectory, depth_fit = d.depth_fit;
    *out = {};
    out->struct_size = sizeof(dvs_render_options);
    out->trajectory = trajectory.c_str();
    out->frames = d.frames;
    out->height = d.height, out->width = d.width;
    out->metric_depth = d.metric_depth, out->hard_points = d.hard_points;
    out->depth_input_size = d.depth_input_size;
    out->squash = d.squash, out->trim_depth = d.trim_depth;
    out->depth_fit = depth_fit.c_str();
    out->fx = d.fx, out->fy = d.fy, out->cx = d.cx, out->cy = d.cy;
    out->export_glb = d.export_glb, out->save_npy = d.save_npy;
    out->depth_cache = d.depth_cache;
  });
}

dvs_status dvs_pipeline_options_default(dvs_pipeline_options* out) {
  using namespace dvs::capi;
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    require(out, "dvs_pipeline_options_default", "out");
    static const dvs::RunOptions d;
    static const std::string preset = d.preset, weights = d.weights;
    *out = {};
    out->struct_size = sizeof(dvs_pipeline_options);
    out->render = nullptr;  // the render defaults
    out->preset = preset.c_str();
    out->steps = d.steps, out->inversion_steps = d.inversion_steps;
    out->strength = d.strength, out->k = d.k, out->delta = d.delta, out->guidance = d.guidance;
    out->lora_scale = d.lora_scale;
    out->seed = d.seed;
    out->use_cache = d.use_cache;
    out->dynamic_cfg = d.dynamic_cfg ? (*d.dynamic_cfg ? 1 : 0) : -1;
    out->preservation_scale = d.preservation_scale;
    out->vae_tiling = d.vae_tiling;
    out->vae_tile_height = d.vae_tile_height, out->vae_tile_width = d.vae_tile_width;
    out->weights = weights.c_str();
  });
}

}  // extern "C"
