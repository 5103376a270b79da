// A model folder as --model and dvs plan read it: model_index.json (spec/model_folder.hpp), the components'
// config.json read into the model's settings and tensor schemas (as preflight does), the transformer's shard
// index (io/weight_set.hpp), and the memory plan from the configs (pipeline/memory_plan.hpp, dvs plan --model DIR).
// The input is cut at harness_input.hpp's separator into those five files, in the order of kFiles.
#include <array>

#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "pipeline/memory_plan.hpp"
#include "spec/cogvideox_config.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "spec/t5_config.hpp"

namespace {

constexpr std::array<const char*, 5> kFiles = {"model_index.json", "transformer/config.json", "vae/config.json",
                                               "text_encoder/config.json",
                                               "transformer/diffusion_pytorch_model.safetensors.index.json"};

template <typename Step>
void attempt(Step step) {
  try {
    step();
  } catch (const dvs::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<std::string_view> parts = dvs::fuzz::split_parts(dvs::fuzz::as_text(data, size), kFiles.size());
  const std::filesystem::path root = dvs::fuzz::scratch_dir() / "model";
  std::filesystem::remove_all(root);
  for (size_t i = 0; i < parts.size(); ++i) dvs::fuzz::write_scratch(std::string("model/") + kFiles[i], parts[i]);
  attempt([&] {
    const dvs::ModelFolder folder = dvs::ModelFolder::open(root);
    for (const dvs::ComponentEntry& c : folder.components()) attempt([&] { (void)folder.load(c.name); });
  });
  attempt([&] {
    const nlohmann::json config = dvs::read_json_file(root / kFiles[1]);
    (void)dvs::CogVideoXTransformerConfig::from_json(config);
    (void)dvs::cogvideox_transformer_schema(config);
  });
  attempt([&] {
    const nlohmann::json config = dvs::read_json_file(root / kFiles[2]);
    (void)dvs::VaeConfig::from_json(config);
    (void)dvs::cogvideox_vae_schema(config);
  });
  attempt([&] {
    const nlohmann::json config = dvs::read_json_file(root / kFiles[3]);
    (void)dvs::T5EncoderConfig::from_json(config);
    (void)dvs::t5_encoder_schema(config);
  });
  attempt([&] { (void)dvs::WeightSet::open_file(root / kFiles[4]); });
  attempt([&] { (void)dvs::pipeline::plan_memory(dvs::pipeline::plan_model_from_folder(root), {}); });
  return 0;
}
