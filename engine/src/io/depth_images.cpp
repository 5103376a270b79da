#include "io/depth_images.hpp"

#ifndef DVS_VIDEO_IO
#define DVS_VIDEO_IO 1  // CMake defines it as 0 for this file in a DVS_VIDEO_IO=OFF build
#endif

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#if DVS_VIDEO_IO
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#endif

#include "dvs/error.hpp"


namespace dvs {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

// One single-channel image as [H,W] f32, through OpenCV (PNG 8/16-bit, EXR float).
HostTensor read_single_channel(const std::filesystem::path& file, const char* kind) {
  const std::string name = file.string();
  if (!std::filesystem::is_regular_file(file)) throw Error(name + ": cannot open the depth image (no such file)");
#if !DVS_VIDEO_IO
  throw Error(name + ": cannot read " + kind + " depth images: built without video I/O (DVS_VIDEO_IO=OFF)");
#else
  cv::Mat img;
  try {
    img = cv::imread(name, cv::IMREAD_UNCHANGED | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception& e) {
    throw Error(name + ": cannot read the " + kind + " depth image (" + e.what() + ")");
  }
  if (img.empty()) throw Error(name + ": not a readable " + kind + " image (corrupt or truncated?)");
  if (img.channels() != 1)
    throw Error(name + ": depth images must be single-channel (grayscale); this one has " +
                std::to_string(img.channels()) + " channels");
  cv::Mat f;
  img.convertTo(f, CV_32F);  // integers keep their stored values
  HostTensor out({int64_t(f.rows), int64_t(f.cols)}, DType::f32);
  for (int y = 0; y < f.rows; ++y) std::memcpy(out.as<float>() + size_t(y) * f.cols, f.ptr<float>(y), size_t(f.cols) * 4);
  return out;
#endif
}

}  // namespace

bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const bool da = std::isdigit(static_cast<unsigned char>(a[i])), db = std::isdigit(static_cast<unsigned char>(b[j]));
    if (da && db) {  // compare the whole digit runs as numbers: without leading zeros, longer is larger
      size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      size_t ia = i, jb = j;
      while (ia + 1 < ie && a[ia] == '0') ++ia;
      while (jb + 1 < je && b[jb] == '0') ++jb;
      if (ie - ia != je - jb) return ie - ia < je - jb;
      const int c = a.compare(ia, ie - ia, b, jb, je - jb);
      if (c != 0) return c < 0;
      if (ie - i != je - j) return ie - i < je - j;  // equal values: fewer leading zeros first
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

HostTensor read_depth_png(const std::filesystem::path& file) { return read_single_channel(file, "PNG"); }

HostTensor read_depth_exr(const std::filesystem::path& file) {
  // OpenCV reads EXR only when this is set before the first EXR read (a security default).
  setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 0);
  return read_single_channel(file, "EXR");
}

std::vector<std::filesystem::path> depth_image_files(const std::filesystem::path& folder) {
  const std::string name = folder.string();
  if (!std::filesystem::is_directory(folder)) throw Error(name + ": not a folder of depth images");
  std::vector<std::filesystem::path> png, exr;
  for (const auto& e : std::filesystem::directory_iterator(folder)) {
    if (!e.is_regular_file()) continue;
    std::string ext = lower_ext(e.path());
    if (ext == ".png") png.push_back(e.path());
    else if (ext == ".exr") exr.push_back(e.path());
  }
  if (!png.empty() && !exr.empty()) throw Error(name + ": holds both .png and .exr files; keep one kind per folder");
  std::vector<std::filesystem::path>& files = png.empty() ? exr : png;
  if (files.empty()) throw Error(name + ": has no .png or .exr depth images (zero frames)");
  std::sort(files.begin(), files.end(), [](const std::filesystem::path& a, const std::filesystem::path& b) {
    return natural_less(a.filename().string(), b.filename().string());
  });
  return files;
}

HostTensor read_depth_image_sequence(const std::filesystem::path& folder) {
  const std::vector<std::filesystem::path> files = depth_image_files(folder);
  const bool png = lower_ext(files[0]) == ".png";
  HostTensor out;
  for (size_t i = 0; i < files.size(); ++i) {
    HostTensor f = png ? read_depth_png(files[i]) : read_depth_exr(files[i]);
    if (i == 0) {
      out = HostTensor({int64_t(files.size()), f.shape[0], f.shape[1]}, DType::f32);
    } else if (f.shape[0] != out.shape[1] || f.shape[1] != out.shape[2]) {
      throw Error(files[i].string() + ": is " + std::to_string(f.shape[0]) + "x" + std::to_string(f.shape[1]) +
                  " (HxW) but " + files[0].filename().string() + " is " + std::to_string(out.shape[1]) + "x" +
                  std::to_string(out.shape[2]));
    }
    std::memcpy(out.data.data() + i * f.data.size(), f.data.data(), f.data.size());
  }
  return out;
}

}  // namespace dvs
