// `dvs-weights inspect --values`: every floating-point weight read and checked for NaN and ±Inf, so a model
// that would give an all-black video is refused before a run spends GPU-minutes on it.
#pragma once
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace dvs::weights_tools {

// The first non-finite element of one tensor's stored bytes.
struct NonFinite {
  uint64_t index = 0;  // flat (C-order) element index
  bool nan = false;    // NaN, else an infinity
};

// `dtype_name` is the safetensors name ("F32", "F16", "BF16", "F64"). Integer and unknown dtypes hold no
// NaN: std::nullopt. Throws dvs::Error when the byte count is not a whole number of elements.
std::optional<NonFinite> first_non_finite(std::span<const uint8_t> bytes, const std::string& dtype_name);

// True for the dtypes first_non_finite can check.
bool is_float_dtype(const std::string& dtype_name);

}  // namespace dvs::weights_tools
