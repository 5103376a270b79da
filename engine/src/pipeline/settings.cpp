#include "pipeline/settings.hpp"

#include <cmath>

#include "dvs/error.hpp"
#include "pipeline/weight_stream_plan.hpp"

namespace dvs {
namespace {

// The official code's fixed negative prompt (docs/design.md §6.7, `NEG` in infer.py).
constexpr const char* kOfficialNegativePrompt =
    "crowded scene, car in the road, bad anatomy, deformed body, occlusions, dark scene, black, unseen regions, "
    "black & white, blurry, pixelated.";

}  // namespace

Settings resolve(const RunOptions& o) {
  if (o.preset != "paper" && o.preset != "official")
    throw Error("--preset must be paper or official, got '" + o.preset + "'");
  Settings s;
  s.official = o.preset == "official";
  s.steps = o.steps > 0 ? o.steps : (s.official ? 30 : 50);
  s.strength = o.strength > 0 ? o.strength : (s.official ? 0.98 : 0.95);
  s.inversion_steps = o.inversion_steps > 0 ? o.inversion_steps : 30;
  s.delta = o.delta > 0 ? o.delta : (s.official ? 2 : 3);
  s.negative = !o.negative_prompt.empty() ? o.negative_prompt : (s.official ? kOfficialNegativePrompt : "");
  if (!(s.strength > 0 && s.strength <= 1)) throw Error("--strength must be in (0, 1], got " + std::to_string(s.strength));
  if (!(o.k > 0)) throw Error("--k must be > 0");
  if (s.official && o.k != std::floor(o.k))  // the official K-RNR is the integer recursion (Σ a·b^i, i < k)
    throw Error("--k must be a whole number with --preset official (the authors' recursion), got " + std::to_string(o.k));
  if (s.official && s.delta != std::floor(s.delta))  // as init_noise's per-element K-RNR requires, found here first
    throw Error("--delta must be a whole number with --preset official (the authors' recursion), got " +
                std::to_string(s.delta));
  if (!(o.guidance >= 0)) throw Error("--guidance must be ≥ 0");
  if (s.steps > 1000 || s.inversion_steps > 1000) throw Error("--steps and --inversion-steps must be ≤ 1000");
  if (o.render.frames != 0 && (o.render.frames - 1) % 4 != 0)
    throw Error("--frames must be 4k+1 (1, 5, 9, …, 49): the VAE compresses time by 4 after the first frame");
  if (!o.lora.empty() && !(o.lora_scale == o.lora_scale)) throw Error("--lora: the scale must be a number");
  pipeline::parse_weights_choice(o.weights, "--weights");  // resident, stream or auto
  if (o.vae_tile_height < 0 || o.vae_tile_width < 0 || o.vae_tile_height % 8 || o.vae_tile_width % 8)
    throw Error("--vae-tile must be positive multiples of 8, got " + std::to_string(o.vae_tile_height) + "x" +
                std::to_string(o.vae_tile_width));
  return s;
}

}  // namespace dvs
