#include "pipeline/settings.hpp"

#include <cmath>
#include <cstdio>

#include "dvs/usage_error.hpp"
#include "io/option_names.hpp"
#include "pipeline/weight_stream_plan.hpp"

namespace dvs {
namespace {

// The official code's fixed negative prompt (docs/design.md §6.7, `NEG` in infer.py).
constexpr const char* kOfficialNegativePrompt =
    "crowded scene, car in the road, bad anatomy, deformed body, occlusions, dark scene, black, unseen regions, "
    "black & white, blurry, pixelated.";

// A value as the user would write it ("-1", "0.95", "nan"), not std::to_string's six decimals.
std::string number_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.10g", v);
  return text;
}

// A number where 0 asks for the preset's default: anything below 0 (or not a number) is refused, naming the field,
// instead of being taken as "unset".
void refuse_negative(double value, const char* field, const std::string& what) {
  if (value >= 0) return;
  throw UsageError(option_name(field) + " is " + number_text(value) + ": give " + what + ", or 0 for the preset's default");
}

}  // namespace

Settings resolve(const RunOptions& o) {
  if (o.preset != "paper" && o.preset != "official")
    throw UsageError(option_name("RunOptions::preset") + " must be paper or official, got '" + o.preset + "'");
  refuse_negative(o.steps, "RunOptions::steps", "a number of sampling steps ≥ 1 (paper 50, official 30)");
  refuse_negative(o.strength, "RunOptions::strength", "a value in (0, 1] (paper 0.95, official 0.98)");
  refuse_negative(o.inversion_steps, "RunOptions::inversion_steps", "a number of inversion steps ≥ 1 (30)");
  refuse_negative(o.delta, "RunOptions::delta", "an AdaIN order > 0 (paper 3, official 2)");
  Settings s;
  s.official = o.preset == "official";
  s.steps = o.steps > 0 ? o.steps : (s.official ? 30 : 50);
  s.strength = o.strength > 0 ? o.strength : (s.official ? 0.98 : 0.95);
  s.inversion_steps = o.inversion_steps > 0 ? o.inversion_steps : 30;
  s.delta = o.delta > 0 ? o.delta : (s.official ? 2 : 3);
  s.negative = !o.negative_prompt.empty() ? o.negative_prompt : (s.official ? kOfficialNegativePrompt : "");
  const std::string k = option_name("RunOptions::k"), delta = option_name("RunOptions::delta");
  if (!(s.strength > 0 && s.strength <= 1))
    throw UsageError(option_name("RunOptions::strength") + " must be in (0, 1], got " + number_text(s.strength));
  if (!(o.k > 0)) throw UsageError(k + " must be > 0, got " + number_text(o.k));
  const std::string official = " with " + option_name("RunOptions::preset") + " official (the authors' recursion), got ";
  if (s.official && o.k != std::floor(o.k))  // the official K-RNR is the integer recursion (Σ a·b^i, i < k)
    throw UsageError(k + " must be a whole number" + official + number_text(o.k));
  if (s.official && s.delta != std::floor(s.delta))  // as init_noise's per-element K-RNR requires, found here first
    throw UsageError(delta + " must be a whole number" + official + number_text(s.delta));
  if (!(o.guidance >= 0)) throw UsageError(option_name("RunOptions::guidance") + " must be ≥ 0, got " + number_text(o.guidance));
  if (s.steps > 1000 || s.inversion_steps > 1000)
    throw UsageError(option_name("RunOptions::steps") + " and " + option_name("RunOptions::inversion_steps") + " must be ≤ 1000");
  if (o.render.frames != 0 && (o.render.frames - 1) % 4 != 0)
    throw UsageError(option_name("RunOptions::render.frames") +
                " must be 4k+1 (1, 5, 9, …, 49): the VAE compresses time by 4 after the first frame");
  if (!o.lora.empty() && !(o.lora_scale == o.lora_scale))
    throw UsageError(option_name("RunOptions::lora_scale") + ": the scale must be a number");
  pipeline::parse_weights_choice(o.weights, option_name("RunOptions::weights"));  // resident, stream or auto
  if (o.vae_tile_height < 0 || o.vae_tile_width < 0 || o.vae_tile_height % 8 || o.vae_tile_width % 8)
    throw UsageError(option_name("RunOptions::vae_tile_height/width") + " must be positive multiples of 8, got " +
                std::to_string(o.vae_tile_height) + "x" + std::to_string(o.vae_tile_width));
  return s;
}

}  // namespace dvs
