// HostTensor helpers and the exact 16-bit float conversions every reader and test relies on.
#include "io/host_tensor.hpp"

#include <bit>
#include <cmath>

#include "dvs/error.hpp"

namespace dvs {

std::string shape_list(const Shape& s) {
  std::string out = "[";
  for (size_t i = 0; i < s.size(); ++i) {
    if (i) out += ",";
    out += std::to_string(s[i]);
  }
  return out + "]";
}

std::string shape_str(const Shape& s) {
  if (s.empty()) return "scalar";
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i) out += 'x';
    out += std::to_string(s[i]);
  }
  return out;
}

HostTensor HostTensor::from_f32(Shape s, std::span<const float> values) {
  for (int64_t d : s)
    if (d < 0) throw Error("HostTensor::from_f32: negative dimension in shape " + shape_str(s));
  if (shape_numel(s) != int64_t(values.size()))
    throw Error("HostTensor::from_f32: shape " + shape_str(s) + " holds " + std::to_string(shape_numel(s)) +
                " values but " + std::to_string(values.size()) + " were given");
  HostTensor t(std::move(s), DType::f32);
  if (!values.empty()) std::memcpy(t.data.data(), values.data(), values.size_bytes());
  return t;
}

std::vector<float> HostTensor::to_f32() const {
  const size_t n = size_t(numel());
  if (data.size() != n * dtype_size(dtype))
    throw Error("HostTensor::to_f32: " + std::to_string(data.size()) + " bytes do not hold shape " +
                shape_str(shape) + " of " + dtype_name(dtype));
  std::vector<float> out(n);
  // memcpy per element: data is a byte vector, so typed loads could be misaligned in principle.
  const uint8_t* p = data.data();
  switch (dtype) {
    case DType::f32:
      if (n) std::memcpy(out.data(), p, n * 4);
      break;
    case DType::f16:
    case DType::bf16:
      for (size_t i = 0; i < n; ++i) {
        uint16_t v;
        std::memcpy(&v, p + 2 * i, 2);
        out[i] = dtype == DType::f16 ? f16_to_f32(v) : bf16_to_f32(v);
      }
      break;
    case DType::i32:
      for (size_t i = 0; i < n; ++i) {
        int32_t v;
        std::memcpy(&v, p + 4 * i, 4);
        out[i] = float(v);
      }
      break;
    case DType::u8:
      for (size_t i = 0; i < n; ++i) out[i] = float(p[i]);
      break;
  }
  return out;
}

float bf16_to_f32(uint16_t v) { return std::bit_cast<float>(uint32_t(v) << 16); }

uint16_t f32_to_bf16(float v) {
  const uint32_t bits = std::bit_cast<uint32_t>(v);
  if ((bits & 0x7fffffffu) > 0x7f800000u) {
    // NaN: truncating could clear every remaining mantissa bit and turn it into Inf; force the quiet bit.
    return uint16_t((bits >> 16) | 0x0040u);
  }
  // Round to nearest, ties to even: add 0x7fff plus the lowest kept bit. Overflow carries into the exponent,
  // which correctly rounds the largest finite values up to Inf.
  const uint32_t lsb = (bits >> 16) & 1u;
  return uint16_t((bits + 0x7fffu + lsb) >> 16);
}

float f16_to_f32(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  const uint32_t exp = (h >> 10) & 0x1fu;
  const uint32_t man = h & 0x3ffu;
  uint32_t bits;
  if (exp == 0x1f) {
    bits = sign | 0x7f800000u | (man << 13);  // Inf or NaN (payload kept)
  } else if (exp != 0) {
    bits = sign | ((exp + 127 - 15) << 23) | (man << 13);
  } else if (man == 0) {
    bits = sign;  // signed zero
  } else {
    // Subnormal half: value = man * 2^-24, exactly representable in f32.
    const float mag = std::ldexp(float(man), -24);
    bits = sign | std::bit_cast<uint32_t>(mag);
  }
  return std::bit_cast<float>(bits);
}

uint16_t f32_to_f16(float v) {
  const uint32_t bits = std::bit_cast<uint32_t>(v);
  const uint16_t sign = uint16_t((bits >> 16) & 0x8000u);
  const uint32_t abs = bits & 0x7fffffffu;
  if (abs > 0x7f800000u) {
    // NaN: keep the top payload bits and make sure the result is still a (quiet) NaN.
    return uint16_t(sign | 0x7c00u | 0x0200u | ((abs >> 13) & 0x3ffu));
  }
  if (abs >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // >= 65520 rounds to Inf (and Inf stays Inf)
  if (abs >= 0x38800000u) {
    // Normal half range (>= 2^-14): rebias the exponent, round the 13 dropped mantissa bits to nearest even.
    const uint32_t lsb = (abs >> 13) & 1u;
    const uint32_t rounded = abs + 0xfffu + lsb;
    return uint16_t(sign | (((rounded >> 13) - ((127u - 15u) << 10)) & 0x7fffu));
  }
  if (abs < 0x33000000u) return sign;  // < 2^-25 (half of the smallest subnormal, tie goes to even 0)
  // Subnormal half: value / 2^-24 rounded to nearest even integer. Work on the integer mantissa so the
  // rounding is exact.
  const uint32_t e = abs >> 23;                   // biased f32 exponent, 102..112
  const uint32_t m = (abs & 0x7fffffu) | 0x800000u;  // 24-bit significand
  const uint32_t shift = 126u - e;                // value = m * 2^(e-150); / 2^-24 -> m >> (126-e)
  uint32_t q = m >> shift;
  const uint32_t rem = m & ((1u << shift) - 1u);
  const uint32_t half = 1u << (shift - 1u);
  if (rem > half || (rem == half && (q & 1u))) ++q;  // may carry into the smallest normal: still correct
  return uint16_t(sign | q);
}

}  // namespace dvs
