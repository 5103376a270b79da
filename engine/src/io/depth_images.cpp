#include "io/depth_images.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "io/video_backend.hpp"


namespace dvs {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

uint32_t big_endian_u32(const unsigned char* p) { return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | p[3]; }
int32_t little_endian_i32(const unsigned char* p) {
  return int32_t(uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24);
}

// The width, height and bytes per pixel the image's header declares (PNG: IHDR; EXR: the dataWindow attribute),
// or zeros when it is not found there (OpenCV then decides).
struct DeclaredSize {
  int64_t width = 0, height = 0, bytes_per_pixel = 0;
};
DeclaredSize declared_size(const std::string& head) {
  const auto* p = reinterpret_cast<const unsigned char*>(head.data());
  DeclaredSize d;
  if (head.size() >= 26 && head.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0 && head.compare(12, 4, "IHDR") == 0) {
    d.width = big_endian_u32(p + 16);
    d.height = big_endian_u32(p + 20);
    const int64_t channels = p[25] == 0 ? 1 : p[25] == 2 ? 3 : p[25] == 4 ? 2 : p[25] == 6 ? 4 : 1;
    d.bytes_per_pixel = std::max<int64_t>(1, channels * p[24] / 8);
    return d;
  }
  if (head.size() < 8 || head.compare(0, 4, "\x76\x2f\x31\x01") != 0) return d;
  // EXR attributes after the 8-byte magic and version: name NUL, type NUL, int32 size, value; an empty name ends them.
  for (size_t i = 8; i < head.size() && head[i] != '\0';) {
    const size_t name_end = head.find('\0', i), type_end = name_end == std::string::npos ? name_end : head.find('\0', name_end + 1);
    if (type_end == std::string::npos || type_end + 4 >= head.size()) break;
    const int32_t size = little_endian_i32(p + type_end + 1);
    const size_t value = type_end + 5;
    if (size < 0 || value + size_t(size) > head.size()) break;
    if (head.compare(i, name_end - i, "dataWindow") == 0 && size == 16) {
      const int64_t x0 = little_endian_i32(p + value), y0 = little_endian_i32(p + value + 4);
      const int64_t x1 = little_endian_i32(p + value + 8), y1 = little_endian_i32(p + value + 12);
      d.width = x1 - x0 + 1;
      d.height = y1 - y0 + 1;
      d.bytes_per_pixel = 4;
      return d;
    }
    i = value + size_t(size);
  }
  return d;
}

// The first bytes of the file (enough for a PNG's IHDR and an EXR's header attributes).
std::string file_head(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string head(64 * 1024, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(size_t(in.gcount()));
  return head;
}

// OpenCV picks its decoder by the file's content, not its name: a ".png" holding DICOM, JPEG 2000 or a raster
// format would reach decoders dvs never meant to run (fuzz_depth_png found Debian's GDCM asserting, which aborts
// the process). So a .png must start with the PNG signature and a .exr with the EXR magic; and since OpenCV 4.6
// tries its DICOM reader (a "DICM" marker at byte 128) before its EXR reader, an EXR carrying that marker is
// refused too.
void check_signature(const std::filesystem::path& file, const std::string& head, const char* kind) {
  const bool png = kind == std::string("PNG");
  const std::string magic = png ? std::string("\x89PNG\r\n\x1a\n", 8) : std::string("\x76\x2f\x31\x01", 4);
  if (head.compare(0, magic.size(), magic) != 0)
    throw Error(file.string() + (png ? ": not a PNG file" : ": not an EXR file") + " (it does not start with the " + kind +
                " signature); depth images must be " + (png ? "8/16-bit grayscale PNG" : "single-channel float EXR"));
  if (!png && head.size() >= 132 && head.compare(128, 4, "DICM") == 0)
    throw Error(file.string() + ": holds a DICOM marker at byte 128, which OpenCV would decode as DICOM, not EXR "
                "(corrupt file?)");
}

// Refuses an image whose header declares more pixels than a depth frame has (kMaxDepthImagePixels) or than a PNG
// of this file's size can hold (deflate expands at most ~1032:1), before OpenCV allocates them.
void check_declared_size(const std::filesystem::path& file, const std::string& head, const char* kind) {
  const DeclaredSize d = declared_size(head);
  if (d.width == 0 && d.height == 0) return;
  const std::string what = file.string() + ": the " + kind + " header declares a " + std::to_string(d.width) + "x" +
                           std::to_string(d.height) + " image";
  if (d.width <= 0 || d.height <= 0 || d.width > kMaxDepthImagePixels || d.height > kMaxDepthImagePixels ||
      d.width * d.height > kMaxDepthImagePixels)
    throw Error(what + "; a depth frame has at most " + std::to_string(kMaxDepthImagePixels) +
                " pixels (corrupt file?)");
  std::error_code ec;
  const uint64_t file_size = std::filesystem::file_size(file, ec);
  if (!ec && kind == std::string("PNG") && uint64_t(d.width * d.height * d.bytes_per_pixel) / 1100 > file_size)
    throw Error(what + ", more than its " + std::to_string(file_size) + " bytes can hold (corrupt file?)");
}

// One single-channel image as [H,W] f32, through the video component (OpenCV: PNG 8/16-bit, EXR float).
HostTensor read_single_channel(const std::filesystem::path& file, const char* kind) {
  const std::string name = file.string();
  if (!std::filesystem::is_regular_file(file)) throw Error(name + ": cannot open the depth image (no such file)");
  const VideoBackend* backend = video_backend();
  if (!backend) needs_video_component(file, std::string("reading ") + kind + " depth images");
  const std::string head = file_head(file);
  check_signature(file, head, kind);
  check_declared_size(file, head, kind);
  return backend->read_depth_image(file, kind);
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

HostTensor read_depth_exr(const std::filesystem::path& file) { return read_single_channel(file, "EXR"); }

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
