#include "value_scan.hpp"

#include <cmath>
#include <cstring>

#include "dvs/error.hpp"

namespace dvs::weights_tools {
namespace {

// Each format is non-finite exactly when its exponent bits are all ones; the mantissa tells NaN from Inf.
template <typename Bits>
std::optional<NonFinite> scan(std::span<const uint8_t> bytes, Bits exp_mask, Bits mantissa_mask) {
  const size_t n = bytes.size() / sizeof(Bits);
  for (size_t i = 0; i < n; ++i) {
    Bits v;
    std::memcpy(&v, bytes.data() + i * sizeof(Bits), sizeof(Bits));
    if ((v & exp_mask) == exp_mask) return NonFinite{uint64_t(i), (v & mantissa_mask) != 0};
  }
  return std::nullopt;
}

}  // namespace

bool is_float_dtype(const std::string& d) { return d == "F32" || d == "F16" || d == "BF16" || d == "F64"; }

std::optional<NonFinite> first_non_finite(std::span<const uint8_t> bytes, const std::string& d) {
  size_t size = d == "F64" ? 8 : d == "F32" ? 4 : (d == "F16" || d == "BF16") ? 2 : 0;
  if (size == 0) return std::nullopt;
  if (bytes.size() % size)
    throw Error("a " + d + " tensor of " + std::to_string(bytes.size()) + " bytes is not a whole number of elements");
  if (d == "F32") return scan<uint32_t>(bytes, 0x7f800000u, 0x007fffffu);
  if (d == "F64") return scan<uint64_t>(bytes, 0x7ff0000000000000ull, 0x000fffffffffffffull);
  if (d == "F16") return scan<uint16_t>(bytes, 0x7c00u, 0x03ffu);
  return scan<uint16_t>(bytes, 0x7f80u, 0x007fu);  // BF16: the top half of an f32
}

}  // namespace dvs::weights_tools
