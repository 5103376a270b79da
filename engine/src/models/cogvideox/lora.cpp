#include "models/cogvideox/lora.hpp"

#include <vector>

#include "io/lora_file.hpp"

namespace dvs::models {

std::map<std::string, LoraAdapter> load_lora(vk::Context& ctx, const std::filesystem::path& file, float scale,
                                             const std::string& prefix) {
  std::map<std::string, LoraAdapter> out;
  for (const auto& [key, ad] : read_lora_file(file, scale, prefix)) {
    std::vector<float> up = ad.b.to_f32();  // the scale folded into B, once
    for (float& x : up) x = float(double(x) * ad.scale);
    LoraAdapter gpu;
    gpu.rank = ad.rank();
    gpu.down = Tensor::upload(ctx, ad.a, "LoRA A " + key);
    gpu.up = Tensor::upload(ctx, HostTensor::from_f32(ad.b.shape, up), "LoRA B " + key);
    out.emplace(key, std::move(gpu));
  }
  return out;
}

}  // namespace dvs::models
