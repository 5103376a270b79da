// The example's inputs as .npy arrays (numpy's format 1.0/2.0, little-endian, C order): a frame u8 [H,W,3]
// ([1,H,W,3] or [F,H,W,3]) or f32 [3,H,W] ([F,3,H,W]) and depth f32 [H,W] ([F,H,W]). Small and self-contained
// so the example needs nothing from dvs beyond its public API; u8 [H,W,4] and f32 screenshots are written too.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace preview {

struct NpyArray {
  std::string dtype;  // "u1" or "f4"
  std::vector<int64_t> shape;
  std::vector<uint8_t> bytes;  // the data, row-major
  int64_t elements() const;
};

// Throws std::runtime_error naming the file and what is wrong (not .npy, big-endian, Fortran order, dtype).
NpyArray read_npy(const std::string& path);
void write_npy(const std::string& path, const std::string& dtype, const std::vector<int64_t>& shape,
               const void* data, size_t bytes);

}  // namespace preview
