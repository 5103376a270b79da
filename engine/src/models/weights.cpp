#include "models/weights.hpp"

#include "dvs/error.hpp"
#include "spec/model_schema.hpp"
#include "vk/context.hpp"

namespace dvs::models {

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

bool ComponentWeights::has(const std::string& name) const {
  return uploaded_.count(name) != 0 || weights_.find(name) != nullptr;
}

const Tensor& ComponentWeights::get(const std::string& name) {
  if (auto it = uploaded_.find(name); it != uploaded_.end()) return it->second;
  if (weights_.find(name) == nullptr)
    throw Error(dir_.string() + ": the weights have no tensor '" + name + "' (is this the right model folder?)");
  HostTensor h = weights_.load(name);
  Tensor t = Tensor::upload(ctx_, h, name);
  bytes_ += t.bytes();
  return uploaded_.emplace(name, std::move(t)).first->second;
}

const Tensor& ComponentWeights::get(const std::string& name, const Shape& expected) {
  const Tensor& t = get(name);
  if (t.shape() != expected)
    throw Error(dir_.string() + ": tensor '" + name + "' has shape [" + shape_str(t.shape()) + "], the config implies [" +
                shape_str(expected) + "]");
  return t;
}

}  // namespace dvs::models
