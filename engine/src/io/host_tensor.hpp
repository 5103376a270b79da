// A tensor in host memory: shape, dtype and the raw little-endian bytes. What file readers produce and
// what uploads consume.
#pragma once
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "io/dtype.hpp"

namespace dvs {

using Shape = std::vector<int64_t>;

inline int64_t shape_numel(const Shape& s) {
  int64_t n = 1;
  for (int64_t d : s) n *= d;
  return n;
}

std::string shape_str(const Shape& s);   // "1x3x8x8"
std::string shape_list(const Shape& s);  // "[1,3,8,8]", as weight files and schemas print shapes

struct HostTensor {
  Shape shape;
  DType dtype = DType::f32;
  std::vector<uint8_t> data;

  HostTensor() = default;
  HostTensor(Shape s, DType t) : shape(std::move(s)), dtype(t), data(size_t(shape_numel(shape)) * dtype_size(t)) {}
  static HostTensor from_f32(Shape s, std::span<const float> values);

  int64_t numel() const { return shape_numel(shape); }
  size_t bytes() const { return data.size(); }
  template <class T> T* as() { return reinterpret_cast<T*>(data.data()); }
  template <class T> const T* as() const { return reinterpret_cast<const T*>(data.data()); }
  // Values converted to f32 whatever the stored dtype (bf16/f16 widened exactly).
  std::vector<float> to_f32() const;
};

// Exact conversions used by readers and tests (round-to-nearest-even on narrowing).
float bf16_to_f32(uint16_t v);
uint16_t f32_to_bf16(float v);
float f16_to_f32(uint16_t v);
uint16_t f32_to_f16(float v);

}  // namespace dvs
