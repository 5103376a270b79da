#include <filesystem>

#include "io/public_call.hpp"
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "geometry/synthetic_scene.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "models/random/tiny_model.hpp"

namespace dvs {

RunOptions prepare_demo(const std::filesystem::path& dir) {
  return public_call("dvs::prepare_demo", [&]() -> RunOptions {
    constexpr int kFrames = 9, kHeight = 96, kWidth = 128;
    const auto inputs = dir / "inputs", model = dir / "model";
    if (std::filesystem::exists(dir) && !std::filesystem::is_directory(dir))
      throw Error(dir.string() + ": exists and is not a folder; the demo writes its scene, a tiny model and the run's " +
                  "outputs into a folder (give a new or an existing folder)");
    std::error_code ec;
    std::filesystem::create_directories(inputs, ec);
    if (ec) throw Error(inputs.string() + ": cannot create the demo's folder (" + ec.message() + "); give another folder");

    geometry::SyntheticSceneSpec spec;
    spec.frames = kFrames;
    spec.height = kHeight;
    spec.width = kWidth;
    spec.K = geometry::Intrinsics::official_default(kWidth, kHeight);
    geometry::RgbdClip clip = geometry::render_synthetic(spec);
    write_video(inputs / "scene.mp4", clip.rgb, 8.0);
    write_npy(inputs / "scene_depth.npy", clip.depth);

    if (!std::filesystem::exists(model / "model_index.json")) {
      models::TinyModelSpec tiny;  // the pack's sizes, with the positional table sized for the demo clip
      tiny.seed = 1;
      tiny.sample_frames = kFrames;
      tiny.sample_height = kHeight / 8;
      tiny.sample_width = kWidth / 8;
      tiny.text_len = 16;
      models::write_tiny_model(model, tiny);
    }

    RunOptions o;
    o.render.video = inputs / "scene.mp4";
    o.render.depth = inputs / "scene_depth.npy";
    o.render.metric_depth = true;
    o.render.trajectory = "loop1";
    o.render.frames = kFrames;
    o.render.height = kHeight;
    o.render.width = kWidth;
    o.render.out_dir = dir / "out";
    o.render.export_glb = false;
    o.model = model;
    o.prompt = "a textured box slides in front of a wall";
    o.steps = 10;
    o.inversion_steps = 5;
    o.cache_dir = dir / "cache";
    return o;
  });
}

}  // namespace dvs
