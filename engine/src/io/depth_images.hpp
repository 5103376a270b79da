// Depth image sequences: a folder of single-channel 16-bit (or 8-bit) PNGs or float EXRs, one file per
// frame, taken in natural file-name order (d_2 before d_10; zero-padded names sort the same either way). PNG integer values
// are returned as they are stored (use DepthOptions::metric_scale for millimetres); EXR reads the channel
// its single channel as float (OpenCV reads both).
#pragma once
#include <filesystem>
#include <vector>
#include <string>

#include "io/host_tensor.hpp"

namespace dvs {

// "Natural" order of file names: digit runs compare as numbers (d_2 < d_10; an equal number with more
// leading zeros sorts after), everything else byte by byte.
bool natural_less(const std::string& a, const std::string& b);

// The depth images of `folder` in frame order: every .png or every .exr (one kind only, natural name order).
// dvs::Error when the folder mixes the kinds or holds neither.
std::vector<std::filesystem::path> depth_image_files(const std::filesystem::path& folder);

// [N,H,W] f32 from depth_image_files(folder). Errors name the file.
HostTensor read_depth_image_sequence(const std::filesystem::path& folder);

// One frame: [H,W] f32. An image whose header declares more than kMaxDepthImagePixels pixels (8192 x 8192), or a
// PNG declaring more than its compressed bytes can hold, is refused before it is decoded.
constexpr int64_t kMaxDepthImagePixels = int64_t(1) << 26;
HostTensor read_depth_png(const std::filesystem::path& file);
HostTensor read_depth_exr(const std::filesystem::path& file);

}  // namespace dvs
