// dvs/option_names.hpp and io/option_names.hpp: one table from each option's C++ field to the dvs program's
// flag that sets it (engine/cli/options.cpp declares those flags).
#include "io/option_names.hpp"

#include <atomic>
#include <map>

#include "dvs/error.hpp"
#include "dvs/option_names.hpp"

namespace dvs {
namespace {

std::atomic<OptionNames> chosen{OptionNames::fields};

const std::map<std::string, std::string>& flags() {
  static const std::map<std::string, std::string> table{
      {"RunOptions::model", "--model"},
      {"RunOptions::prompt", "--prompt"},
      {"RunOptions::negative_prompt", "--negative-prompt"},
      {"RunOptions::preset", "--preset"},
      {"RunOptions::steps", "--steps"},
      {"RunOptions::strength", "--strength"},
      {"RunOptions::inversion_steps", "--inversion-steps"},
      {"RunOptions::k", "--k"},
      {"RunOptions::delta", "--delta"},
      {"RunOptions::guidance", "--guidance"},
      {"RunOptions::dynamic_cfg", "--dynamic-cfg"},
      {"RunOptions::preservation_scale", "--preservation-scale"},
      {"RunOptions::seed", "--seed"},
      {"RunOptions::cache_dir", "--cache-dir"},
      {"RunOptions::use_cache", "--no-cache"},
      {"RunOptions::lora", "--lora"},
      {"RunOptions::lora_scale", "--lora FILE:SCALE"},
      {"RunOptions::vae_tiling", "--vae-tiling"},
      {"RunOptions::vae_tile_height/width", "--vae-tile"},
      {"RunOptions::weights", "--weights"},
      {"RenderJob::video", "--video"},
      {"RenderJob::depth", "--depth"},
      {"RenderJob::out_dir", "--out"},
      {"RenderJob::depth_model", "--depth-model"},
      {"RenderJob::depth_input_size", "--depth-input-size"},
      {"RenderJob::depth_cache_dir", "--cache-dir"},
      {"RenderJob::depth_cache", "--no-cache"},
      {"RenderJob::trajectory", "--trajectory"},
      {"RenderJob::frames", "--frames"},
      {"RenderJob::height/width", "--size"},
      {"RenderJob::squash", "--resize"},
      {"RenderJob::metric_depth", "--metric-depth"},
      {"RenderJob::trim_depth", "--trim-depth"},
      {"RenderJob::depth_fit", "--depth-fit"},
      {"RenderJob::fx/fy/cx/cy", "--intrinsics"},
      {"RenderJob::hard_points", "--points"},
      {"RenderJob::export_glb", "--no-glb"},
      {"RenderJob::save_npy", "--save-npy"},
      {"RenderJob::device", "--device"},
      {"DepthJob::video", "--video"},
      {"DepthJob::model", "--depth-model"},
      {"DepthJob::input_size", "--input-size"},
      {"DepthJob::frames", "--frames"},
      {"DepthJob::max_res", "--max-res"},
      {"DepthJob::cache_dir", "--cache-dir"},
      {"DepthJob::device", "--device"},
      {"MemoryPlanRequest::model", "--model"},
      {"MemoryPlanRequest::frames", "--frames"},
      {"MemoryPlanRequest::height", "--height"},
      {"MemoryPlanRequest::width", "--width"},
      {"MemoryPlanRequest::alignment", "--alignment"},
      {"MemoryPlanRequest::depth_model", "--depth-model"},
      {"MemoryPlanRequest::weights", "--weights"},
      {"MemoryPlanRequest::upload_bytes_per_second", "--upload-rate"},
  };
  return table;
}

// "RunOptions::render.x" is the RenderJob field x.
std::string table_key(const std::string& field) {
  const std::string nested = "RunOptions::render.";
  return field.rfind(nested, 0) == 0 ? "RenderJob::" + field.substr(nested.size()) : field;
}

}  // namespace

void set_option_names(OptionNames names) { chosen = names; }

std::string option_flag(const std::string& field) {
  const auto it = flags().find(table_key(field));
  if (it == flags().end()) throw Error("internal: no command-line flag for the option " + field);
  return it->second;
}

std::vector<std::string> option_fields() {
  std::vector<std::string> out;
  for (const auto& [field, flag] : flags()) out.push_back(field);
  return out;
}

std::string in_words_of_caller(const std::string& command_line, const std::string& library) {
  return chosen == OptionNames::command_line ? command_line : library;
}

std::string option_name(const std::string& field) {
  const std::string flag = option_flag(field);  // checked in every mode, so a new name is caught by any test
  return chosen == OptionNames::command_line ? flag : field;
}

}  // namespace dvs
