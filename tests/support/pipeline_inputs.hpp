// The synthetic scene (9 frames of 64×64, exact metric depth) that `dvs run` tests feed the conformance pack's
// tiny model (its positional table fixes that size), and the command line a user would type for it.
#pragma once
#include <filesystem>
#include <string>

#include "dvs/pipeline.hpp"
#include "geometry/synthetic_scene.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs::test {

struct PipelineInputs {
  TempDir dir;
  std::filesystem::path video = dir / "scene.mp4", depth = dir / "depth.npy", cache = dir / "cache";
  std::filesystem::path model = golden_path() / "model";
  PipelineInputs() {
    geometry::SyntheticSceneSpec spec;
    spec.frames = 9;
    spec.height = 64;
    spec.width = 64;
    spec.K = geometry::Intrinsics::official_default(64, 64);
    auto clip = geometry::render_synthetic(spec);
    write_video(video, clip.rgb, 10.0);
    write_npy(depth, clip.depth);
  }
  // The inputs, model, size and schedule options every `dvs run`/`dvs invert` test shares.
  std::string inputs() const {
    return " --video " + video.string() + " --depth " + depth.string() + " --metric-depth --model " + model.string() +
           " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --cache-dir " + cache.string();
  }
  // Exact depth of the same 64×64 scene with another frame count, for inputs whose length must not match.
  static void write_scene_depth(const std::filesystem::path& file, int frames) {
    geometry::SyntheticSceneSpec spec;
    spec.frames = frames;
    spec.height = 64;
    spec.width = 64;
    spec.K = geometry::Intrinsics::official_default(64, 64);
    write_npy(file, geometry::render_synthetic(spec).depth);
  }
  // The same options for run_pipeline (RunOptions), writing to `out`, caching in `cache_dir`.
  RunOptions run_options(const std::filesystem::path& out, const std::filesystem::path& cache_dir) const {
    RunOptions o;
    o.render.video = video;
    o.render.depth = depth;
    o.render.metric_depth = true;
    o.render.frames = 9;
    o.render.height = o.render.width = 64;
    o.render.out_dir = out;
    o.model = model;
    o.steps = 4;
    o.inversion_steps = 3;
    o.cache_dir = cache_dir;
    o.prompt = "a red fox";
    return o;
  }
  std::string command(const std::filesystem::path& out, const std::string& extra = "") const {
    return program("dvs") + " run" + inputs() + " --prompt 'a red fox' --progress json --out " + out.string() + " " + extra;
  }
};

}  // namespace dvs::test
