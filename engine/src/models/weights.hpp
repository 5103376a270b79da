// The weights of one model component on the device: opened from its folder (single or sharded
// safetensors), checked against the schema its config.json implies, and uploaded tensor by tensor in the
// stored dtype (bf16 stays bf16; shaders widen it), except GEMM weights a model asks for in its tensor cores'
// operand type (store_as). A missing or mismatched tensor is an error naming it.
#pragma once
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "spec/model_folder.hpp"
#include "tensor/ops_conv_weights.hpp"
#include "tensor/tensor.hpp"

namespace dvs::vk {
class Context;
}

namespace dvs::models {

// Where a model's repeated blocks keep their weights: on the device for the model's life (resident), or in
// host memory, streamed to a few device slots block by block behind the compute (models/block_stream.hpp).
// Results are byte-identical either way.
enum class WeightResidency { resident, stream };
const char* residency_name(WeightResidency r);  // "resident", "stream"

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
  std::vector<std::string> names() const;  // every tensor, on the device or in the files, sorted
  // The device tensor for `name` (uploaded on first use, in its stored dtype).
  const Tensor& get(const std::string& name);
  // Same, with the shape checked (an error names the tensor, the expected and the stored shape).
  const Tensor& get(const std::string& name, const Shape& expected);
  uint64_t bytes_on_device() const { return bytes_; }

  // Streamed weights (models/block_stream.hpp) stay in host memory: what a tensor is without uploading it,
  // its shape checked the same way, its stored bytes copied to host memory, and a device copy given back.
  struct Info {
    Shape shape;
    DType dtype = DType::f32;
    uint64_t bytes = 0;
  };
  Info info(const std::string& name) const;
  void check(const std::string& name, const Shape& expected) const;
  // Writes info(name).bytes stored bytes to `dst`: from the mapped file, or from the device (in-memory weights).
  void copy_to_host(const std::string& name, void* dst) const;
  // Drops the device copy of `name` (in-memory weights: the tensor itself, so copy it out first).
  void release(const std::string& name);

  // GEMM operands (docs/devices.md, linear_weights_fp16): `name`, when stored bf16, is kept as `dtype` (only f16,
  // the tensor cores' operand type), converted once: weights from files as they are read (get() uploads f16,
  // info() says f16, copy_to_host() writes f16, so a streamed block's host copy is f16 too); weights already on
  // the device by ops::cast now (values past fp16's range become ±Inf: only benchmarks' random weights live
  // there). Round to nearest even, as the GEMM kernel's per-element conversion does, so a tensor-core GEMM
  // computes the same bits. A file tensor holding a finite value past fp16's range (|v| > 65504) stays bf16, so
  // that no fp32 kernel reads an Inf the checkpoint does not hold. Returns whether `name` is now f16.
  bool store_as(const std::string& name, DType dtype);

  // Convolution weights `name` packed once into the layout the conv kernels read (ops_conv_weights.hpp), in the
  // device's conv operand type (bf16 kept fp16 through store_as where ops::conv_weight_dtype says so), on first
  // use; the stored device copy is dropped then (the packed one replaces it: has() stays true, get() of a tensor
  // that lived only on the device is an error). Every call after returns the same packed weights.
  const ops::PackedConvWeights& packed_conv(const std::string& name);

 private:
  vk::Context& ctx_;
  std::filesystem::path dir_;
  nlohmann::json config_;
  WeightSet weights_;
  std::map<std::string, Tensor> uploaded_;
  std::set<std::string> as_f16_;  // file tensors stored bf16 that are read as f16 (store_as)
  std::map<std::string, ops::PackedConvWeights> packed_;  // packed_conv
  uint64_t bytes_ = 0;
};

}  // namespace dvs::models
