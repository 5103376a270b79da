#include "models/weights.hpp"

#include <cstring>
#include <set>

#include "dvs/error.hpp"
#include "spec/model_schema.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "vk/context.hpp"
#include "vk/transfer.hpp"

namespace dvs::models {

namespace {

// bf16 words to fp16 words, rounded to nearest even (io/host_tensor.hpp's conversions).
void bf16_to_f16_in_place(uint16_t* v, size_t n) {
  for (size_t i = 0; i < n; ++i) v[i] = f32_to_f16(bf16_to_f32(v[i]));
}

}  // namespace

const char* residency_name(WeightResidency r) { return r == WeightResidency::stream ? "stream" : "resident"; }

ComponentWeights::ComponentWeights(vk::Context& ctx, const std::filesystem::path& component_dir)
    : ctx_(ctx),
      dir_(component_dir),
      config_(read_json_file(component_dir / "config.json", "check that this is a model component folder")),
      weights_(WeightSet::open_dir(component_dir)) {
  std::string cls = config_class_name(config_);
  if (has_schema(cls))
    require_schema(schema_for(cls, config_, (component_dir / "config.json").string()), weights_, component_dir.string());
}

ComponentWeights::ComponentWeights(vk::Context& ctx, nlohmann::json config, std::map<std::string, Tensor> tensors,
                                   const std::string& origin)
    : ctx_(ctx), dir_(origin), config_(std::move(config)), uploaded_(std::move(tensors)) {
  std::string cls = config_class_name(config_);
  if (has_schema(cls)) {
    std::vector<std::pair<std::string, Shape>> found;
    for (const auto& [name, t] : uploaded_) found.emplace_back(name, t.shape());
    const auto issues = check_schema(schema_for(cls, config_, origin), found);
    if (!issues.empty()) throw Error(origin + ": " + issues.front().message());
  }
  for (const auto& [name, t] : uploaded_) bytes_ += t.bytes();
}

std::vector<std::string> ComponentWeights::names() const {
  std::set<std::string> all;
  for (const auto& [name, t] : uploaded_) all.insert(name);
  for (const auto& [name, p] : packed_) all.insert(name);
  for (const auto& [name, ref] : weights_.entries()) all.insert(name);
  return {all.begin(), all.end()};
}

bool ComponentWeights::has(const std::string& name) const {
  return uploaded_.count(name) != 0 || packed_.count(name) != 0 || weights_.find(name) != nullptr;
}

const Tensor& ComponentWeights::get(const std::string& name) {
  if (auto it = uploaded_.find(name); it != uploaded_.end()) return it->second;
  if (packed_.count(name) && weights_.find(name) == nullptr)
    throw Error("internal: ComponentWeights::get: '" + name + "' lives only on the device and was packed (packed_conv)");
  if (weights_.find(name) == nullptr)
    throw Error(dir_.string() + ": the weights have no tensor '" + name + "' (is this the right model folder?)");
  HostTensor h = weights_.load(name);
  if (as_f16_.count(name)) {
    bf16_to_f16_in_place(h.as<uint16_t>(), size_t(h.numel()));
    h.dtype = DType::f16;
  }
  Tensor t = Tensor::upload(ctx_, h, name);
  bytes_ += t.bytes();
  return uploaded_.emplace(name, std::move(t)).first->second;
}

ComponentWeights::Info ComponentWeights::info(const std::string& name) const {
  if (auto it = uploaded_.find(name); it != uploaded_.end())
    return {it->second.shape(), it->second.dtype(), it->second.bytes()};
  const WeightRef* ref = weights_.find(name);
  if (!ref) throw Error(dir_.string() + ": the weights have no tensor '" + name + "' (is this the right model folder?)");
  if (!ref->info->dtype)
    throw Error(dir_.string() + ": tensor '" + name + "' has dtype " + ref->info->dtype_name + ", which dvs cannot use");
  return {ref->info->shape, as_f16_.count(name) ? DType::f16 : *ref->info->dtype, ref->info->nbytes()};
}

void ComponentWeights::check(const std::string& name, const Shape& expected) const {
  const Shape shape = info(name).shape;
  if (shape != expected)
    throw Error(dir_.string() + ": tensor '" + name + "' has shape [" + shape_str(shape) + "], the config implies [" +
                shape_str(expected) + "]");
}

void ComponentWeights::copy_to_host(const std::string& name, void* dst) const {
  if (auto it = uploaded_.find(name); it != uploaded_.end()) {
    ctx_.transfer().download(it->second.buffer(), dst, size_t(it->second.bytes()));
    return;
  }
  const Info i = info(name);
  const TensorBytes bytes = weights_.bytes(name);
  if (bytes.size() != i.bytes) throw Error("internal: tensor '" + name + "': stored bytes differ from its header");
  std::memcpy(dst, bytes.data(), bytes.size());
  if (as_f16_.count(name)) bf16_to_f16_in_place(static_cast<uint16_t*>(dst), bytes.size() / 2);
}

bool ComponentWeights::store_as(const std::string& name, DType dtype) {
  if (dtype != DType::f16) throw Error("internal: ComponentWeights::store_as: only f16 is supported");
  if (auto it = uploaded_.find(name); it != uploaded_.end()) {
    if (it->second.dtype() != DType::bf16) return it->second.dtype() == DType::f16;
    Tensor f16 = Tensor::empty(ctx_, it->second.shape(), DType::f16, name);
    ops::run_now(ctx_, [&](vk::Recorder& rec) { ops::cast(rec, it->second, f16); });
    it->second = std::move(f16);
    return true;
  }
  if (as_f16_.count(name)) return true;
  if (info(name).dtype != DType::bf16) return false;
  const TensorBytes bytes = weights_.bytes(name);
  const auto* v = reinterpret_cast<const uint16_t*>(bytes.data());
  for (size_t i = 0; i < bytes.size() / 2; ++i)
    if ((v[i] & 0x7fffu) >= 0x4780u && (v[i] & 0x7fffu) < 0x7f80u) return false;  // finite, rounds past 65504
  as_f16_.insert(name);
  return true;
}

const ops::PackedConvWeights& ComponentWeights::packed_conv(const std::string& name) {
  if (auto it = packed_.find(name); it != packed_.end()) return it->second;
  if (ops::conv_weight_dtype(ctx_.caps()) == DType::f16) store_as(name, DType::f16);
  ops::PackedConvWeights p = ops::packed_conv_weights_now(ctx_, get(name), name);
  release(name);
  bytes_ += p.packed.bytes();
  return packed_.emplace(name, std::move(p)).first->second;
}

void ComponentWeights::release(const std::string& name) {
  auto it = uploaded_.find(name);
  if (it == uploaded_.end()) return;
  bytes_ -= it->second.bytes();
  uploaded_.erase(it);
}

const Tensor& ComponentWeights::get(const std::string& name, const Shape& expected) {
  const Tensor& t = get(name);
  if (t.shape() != expected)
    throw Error(dir_.string() + ": tensor '" + name + "' has shape [" + shape_str(t.shape()) + "], the config implies [" +
                shape_str(expected) + "]");
  return t;
}

}  // namespace dvs::models
