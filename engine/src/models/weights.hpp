// The weights of one model component on the device: opened from its folder (single or sharded
// safetensors), checked against the schema its config.json implies, and uploaded tensor by tensor in the
// stored dtype (bf16 stays bf16; shaders widen it). A missing or mismatched tensor is an error naming it.
#pragma once
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "spec/model_folder.hpp"
#include "tensor/tensor.hpp"

namespace dvs::vk {
class Context;
}

namespace dvs::models {

class ComponentWeights {
 public:
  // `component_dir` is e.g. <model>/transformer; its config.json picks the schema.
  ComponentWeights(vk::Context& ctx, const std::filesystem::path& component_dir);
  // Weights already on the device (benchmarks build random weights there; no folder, nothing on disk):
  // `config` is the component's config.json content, `tensors` every tensor by name (shape-checked against
  // the schema `config` implies, as a folder is). `origin` names the set in error messages.
  ComponentWeights(vk::Context& ctx, nlohmann::json config, std::map<std::string, Tensor> tensors,
                   const std::string& origin);

  const nlohmann::json& config() const { return config_; }
  const std::filesystem::path& dir() const { return dir_; }
  bool has(const std::string& name) const;
  // The device tensor for `name` (uploaded on first use, in its stored dtype).
  const Tensor& get(const std::string& name);
  // Same, with the shape checked (an error names the tensor, the expected and the stored shape).
  const Tensor& get(const std::string& name, const Shape& expected);
  uint64_t bytes_on_device() const { return bytes_; }

 private:
  vk::Context& ctx_;
  std::filesystem::path dir_;
  nlohmann::json config_;
  WeightSet weights_;
  std::map<std::string, Tensor> uploaded_;
  uint64_t bytes_ = 0;
};

}  // namespace dvs::models
