// The SPIR-V modules compiled from shaders/ at build time, looked up by their path without extension
// ("nn/groupnorm").
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace dvs::vk {

std::span<const uint32_t> find_shader(const std::string& name);  // throws dvs::Error when unknown
std::vector<std::string> shader_names();
uint64_t shaders_hash();  // changes whenever any embedded shader changes (keys the pipeline cache)

}  // namespace dvs::vk
