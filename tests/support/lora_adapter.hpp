// A random LoRA adapter in the diffusers layout load_lora reads (transformer.<module>.lora_A/B.weight), for
// the pack's transformer, written as DIR/adapter.safetensors. Values come from a fixed LCG seeded by `seed`,
// uniform in ±amplitude/2 (lora_A scaled by a_amplitude, lora_B by 1), A then B for each module in order.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "io/host_tensor.hpp"
#include "io/safetensors_writer.hpp"

namespace dvs::test {

inline std::filesystem::path write_lora_adapter(const std::filesystem::path& dir, const std::vector<std::string>& modules,
                                                uint32_t seed, float a_amplitude, int64_t dim = 32, int64_t rank = 4) {
  std::vector<std::pair<std::string, HostTensor>> tensors;
  uint32_t state = seed;
  auto values = [&](size_t n, float amplitude) {
    std::vector<float> v(n);
    for (auto& x : v) x = amplitude * (float((state = state * 1664525u + 1013904223u) >> 8) / float(1 << 24) - 0.5f);
    return v;
  };
  for (const std::string& module : modules) {
    const std::string name = "transformer." + module;
    tensors.push_back({name + ".lora_A.weight", HostTensor::from_f32({rank, dim}, values(size_t(rank * dim), a_amplitude))});
    tensors.push_back({name + ".lora_B.weight", HostTensor::from_f32({dim, rank}, values(size_t(dim * rank), 1.0f))});
  }
  const std::filesystem::path file = dir / "adapter.safetensors";
  write_safetensors(file, tensors);
  return file;
}

}  // namespace dvs::test
