// Depth images through OpenCV's imgcodecs (the video component): what io/depth_images.hpp reads per frame.
#pragma once
#include <filesystem>

#include "io/host_tensor.hpp"

namespace dvs {

// One single-channel image as [H,W] f32 (kind "PNG": 8/16-bit integers kept as stored; "EXR": float). The caller
// has checked that the file exists and that its header's size is sane (io/depth_images.cpp).
HostTensor opencv_read_depth_image(const std::filesystem::path& file, const char* kind);

}  // namespace dvs
