#include "io/depth_images.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "dvs/error.hpp"

#ifdef DVS_HAVE_LIBPNG
#include <png.h>
#include <csetjmp>
#endif
#ifdef DVS_HAVE_OPENEXR
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <Imath/ImathBox.h>
#endif

namespace dvs {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

#ifdef DVS_HAVE_LIBPNG
struct PngErr {
  std::string message;
};
void png_error_fn(png_structp png, png_const_charp msg) {
  static_cast<PngErr*>(png_get_error_ptr(png))->message = msg;
  png_longjmp(png, 1);
}
void png_warning_fn(png_structp, png_const_charp) {}
#endif

}  // namespace

HostTensor read_depth_png(const std::filesystem::path& file) {
  const std::string name = file.string();
#ifdef DVS_HAVE_LIBPNG
  FILE* fp = std::fopen(name.c_str(), "rb");
  if (!fp) throw Error(name + ": cannot open the depth image");
  uint8_t sig[8] = {};
  if (std::fread(sig, 1, 8, fp) != 8 || png_sig_cmp(sig, 0, 8) != 0) {
    std::fclose(fp);
    throw Error(name + ": not a PNG file");
  }
  PngErr err;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &err, png_error_fn, png_warning_fn);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(fp);
    throw Error(name + ": out of memory reading the PNG");
  }
  HostTensor out;
  std::vector<uint8_t> pixels;
  std::vector<png_bytep> rows;
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(fp);
    throw Error(name + ": corrupt or truncated PNG (" + err.message + ")");
  }
  png_init_io(png, fp);
  png_set_sig_bytes(png, 8);
  png_read_info(png, info);
  png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
  int depth = png_get_bit_depth(png, info), type = png_get_color_type(png, info);
  if (type != PNG_COLOR_TYPE_GRAY && type != PNG_COLOR_TYPE_GRAY_ALPHA) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(fp);
    throw Error(name + ": depth PNGs must be single-channel (grayscale), this one has colour");
  }
  if (w == 0 || h == 0 || uint64_t(w) * h > (uint64_t(1) << 30)) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(fp);
    throw Error(name + ": unreasonable PNG size " + std::to_string(w) + "x" + std::to_string(h));
  }
  if (depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (depth == 16) png_set_swap(png);  // PNG stores big-endian
  if (type == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_strip_alpha(png);
  png_read_update_info(png, info);
  const size_t bpp = depth == 16 ? 2 : 1;
  pixels.resize(size_t(w) * h * bpp);
  rows.resize(h);
  for (png_uint_32 y = 0; y < h; ++y) rows[y] = pixels.data() + size_t(y) * w * bpp;
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  std::fclose(fp);
  out = HostTensor({int64_t(h), int64_t(w)}, DType::f32);
  float* o = out.as<float>();
  for (size_t i = 0; i < size_t(w) * h; ++i) {
    if (bpp == 2) {
      uint16_t v;
      std::memcpy(&v, pixels.data() + 2 * i, 2);
      o[i] = float(v);
    } else {
      o[i] = float(pixels[i]);
    }
  }
  return out;
#else
  throw Error(name + ": this dvs was built without libpng, so PNG depth sequences cannot be read (use .npy)");
#endif
}

HostTensor read_depth_exr(const std::filesystem::path& file) {
  const std::string name = file.string();
#ifdef DVS_HAVE_OPENEXR
  try {
    Imf::InputFile in(name.c_str());
    const Imf::ChannelList& channels = in.header().channels();
    std::string pick;
    for (const char* c : {"Z", "Y", "R"})
      if (channels.findChannel(c)) {
        pick = c;
        break;
      }
    if (pick.empty()) {
      int n = 0;
      for (auto it = channels.begin(); it != channels.end(); ++it, ++n) pick = it.name();
      if (n != 1) throw Error(name + ": EXR has no channel Z, Y or R and not exactly one channel");
    }
    Imath::Box2i dw = in.header().dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1, h = int64_t(dw.max.y) - dw.min.y + 1;
    if (w <= 0 || h <= 0 || w * h > (int64_t(1) << 30)) throw Error(name + ": unreasonable EXR size");
    HostTensor out({h, w}, DType::f32);
    float* base = out.as<float>() - (int64_t(dw.min.y) * w + dw.min.x);
    Imf::FrameBuffer fb;
    fb.insert(pick.c_str(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base), sizeof(float), sizeof(float) * size_t(w)));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    return out;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(name + ": cannot read the EXR depth image (" + e.what() + ")");
  }
#else
  throw Error(name + ": this dvs was built without OpenEXR, so EXR depth sequences cannot be read (use .npy)");
#endif
}

HostTensor read_depth_image_sequence(const std::filesystem::path& folder) {
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
  std::sort(files.begin(), files.end());
  HostTensor out;
  for (size_t i = 0; i < files.size(); ++i) {
    HostTensor f = png.empty() ? read_depth_exr(files[i]) : read_depth_png(files[i]);
    if (i == 0) {
      out = HostTensor({int64_t(files.size()), f.shape[0], f.shape[1]}, DType::f32);
    } else if (f.shape[0] != out.shape[1] || f.shape[1] != out.shape[2]) {
      throw Error(files[i].string() + ": is " + std::to_string(f.shape[1]) + "x" + std::to_string(f.shape[0]) +
                  " but " + files[0].filename().string() + " is " + std::to_string(out.shape[2]) + "x" +
                  std::to_string(out.shape[1]));
    }
    std::memcpy(out.data.data() + i * f.data.size(), f.data.data(), f.data.size());
  }
  return out;
}

}  // namespace dvs
