// `dvs invert`: stages 1–5 of the pipeline alone, writing ε_inv and filling the cache that `dvs run` reads.
#include "dvs/error.hpp"
#include "io/public_call.hpp"
#include "dvs/pipeline.hpp"
#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/preflight.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/output_lock.hpp"
#include "pipeline/run_outputs.hpp"
#include "pipeline/stage_tracker.hpp"
#include "vk/context.hpp"

namespace dvs {
namespace {

InversionReport invert_stages(const RunOptions& options, StageTracker& stages) {
  RunOptions o = options;
  require_preflight(o, JobKind::invert);  // every problem knowable now, before any device work
  const OutputLock out_lock(o.render.out_dir);  // held to the end: one process writes into a folder at a time
  JobPlan jp = plan_job(o);
  // --depth-model: the depth estimated (or cached) in a context of its own, released before the models load.
  depth_stage(o, stages);
  vk::ContextOptions copt;
  copt.device = o.render.device;
  copt.cache_dir = o.cache_dir;  // the pipeline cache beside the run caches, as DVS_CACHE_DIR puts it
  vk::Context ctx(copt);
  // Ctrl-C and progress between the bounded submissions inside a forward or a VAE call, not only between steps.
  const vk::ScopedSegmentHook between_submissions(ctx, stages.segment_hook());

  RenderedInput in = render_for_model(ctx, o, stages);
  const int F = int(in.rgb.shape[0]);

  const WeightResidencies residency = weight_residencies(ctx, o);
  stages.begin("encode", "VAE-encoding the render");
  EncodedRender enc;
  {
    models::CogVideoXVae vae(ctx, o.model / "vae");  // freed before the transformer loads
    enc = encode_render(ctx, vae, o, jp.settings, in);
  }
  stages.end();

  stages.begin("text", "encoding the empty prompt");
  Tensor text_empty;
  {
    models::T5Encoder t5(ctx, o.model / "text_encoder", residency.text_encoder);
    text_empty = t5.encode_prompts(jp.tokenizer, {""}, jp.text_len);
  }
  stages.end();

  stages.begin("invert", "DDIM inversion");
  auto transformer = load_transformer(ctx, o, residency.transformer);
  InversionResult inv = invert_render(ctx, *transformer, o, jp, F, enc, text_empty, stages);
  stages.end();

  stages.begin("write", "writing eps_inv.npy");
  RunOutputs files(o.render.out_dir);
  InversionReport report;
  const HostTensor eps = inv.eps.download(ctx);
  files.write([&] { write_npy(files.add("eps_inv.npy"), eps); });
  report.eps_inv_npy = files.final_path("eps_inv.npy");
  stages.end();
  stages.check_cancelled();
  files.commit();
  report.stages = stages.times();
  report.from_cache = inv.from_cache;
  report.cache_file = inv.cache_file;
  report.shape = inv.eps.shape();
  report.t0 = jp.plan.t0();
  return report;
}

}  // namespace

InversionReport run_inversion(const RunOptions& o, const ProgressFn& progress, const CancelFn& cancelled) {
  return public_call("dvs::run_inversion", [&]() -> InversionReport {
    StageTracker stages(progress, cancelled);
    stages.set_memory_advice([&o](const std::string& stage) { return out_of_memory_advice(o, stage); });
    CreatedFolders out_folder(o.render.out_dir);  // removed again if the inversion fails before filling it
    InversionReport report = stages.run([&] { return invert_stages(o, stages); });
    out_folder.keep();
    return report;
  });
}

}  // namespace dvs
