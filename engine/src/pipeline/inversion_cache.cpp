#include "pipeline/inversion_cache.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "dvs/error.hpp"
#include "io/cache_root.hpp"
#include "io/npy.hpp"
#include "pipeline/cache_entry.hpp"

namespace dvs {
namespace {

struct Fnv {
  uint64_t h = 1469598103934665603ull;
  void add(const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    for (size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  }
  void add(const std::string& s) {
    add(s.data(), s.size());
    add("\0", 1);
  }
  std::string hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
  }
};

}  // namespace

InversionCache::InversionCache(const std::filesystem::path& cache_dir, std::string prefix)
    : dir_(cache_entries_folder(cache_root(cache_dir))), prefix_(std::move(prefix)) {}

std::string InversionCache::key(const std::vector<std::string>& parts) {
  Fnv f;
  for (const auto& p : parts) f.add(p);
  return f.hex();
}

std::string InversionCache::bytes_key(const void* data, size_t bytes) {
  Fnv f;
  f.add(data, bytes);
  return f.hex();
}

std::filesystem::path InversionCache::file(const std::string& key) const { return dir_ / (prefix_ + "-" + key + ".npy"); }

Tensor InversionCache::load(vk::Context& ctx, const std::string& key, const Shape& shape, std::string* rejected) const {
  const CacheEntryRead entry = read_cache_entry(file(key));
  if (!entry.tensor && entry.problem.empty()) return {};
  std::string why = entry.problem;
  if (const auto& h = entry.tensor; h && (h->shape != shape || h->dtype != DType::f32)) {
    why = std::string("it holds ") + dtype_name(h->dtype) + " [" + shape_str(h->shape) + "], not the expected f32 [" + shape_str(shape) + "]";
  } else if (h) {
    // Read on the host anyway: checked here, before a NaN entry could turn every later run black.
    const float* v = h->as<float>();
    int64_t bad = 0, first = -1;
    for (int64_t i = 0; i < h->numel(); ++i)
      if (!std::isfinite(v[i])) bad++, first = first < 0 ? i : first;
    if (bad == 0) {
      // Reused now: `dvs cache clean` removes the least recently used entries first.
      std::error_code ec;
      std::filesystem::last_write_time(file(key), std::filesystem::file_time_type::clock::now(), ec);
      return Tensor::upload(ctx, *h, "cached inversion");
    }
    why = std::to_string(bad) + " non-finite values (NaN/Inf), the first at flat index " + std::to_string(first);
  }
  remove_cache_entry(file(key));
  if (rejected) *rejected = file(key).string() + ": " + why + "; removed, computing it again";
  return {};
}

std::string InversionCache::store(vk::Context& ctx, const std::string& key, const Tensor& latent) const {
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  try {
    write_cache_entry(file(key), latent.download(ctx));
  } catch (const Error& e) {
    return e.what();  // an unwritable cache only costs time on the next run
  }
  return {};
}

std::string model_fingerprint(const std::filesystem::path& model) {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(model))
    if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  Fnv f;
  for (const auto& p : files) {
    const std::string ext = p.extension().string();
    if (ext != ".json" && ext != ".safetensors" && ext != ".model") continue;
    f.add(std::filesystem::relative(p, model).string());
    std::ifstream in(p, std::ios::binary);
    const uint64_t size = std::filesystem::file_size(p);
    f.add(&size, sizeof size);
    std::string head(size_t(std::min<uint64_t>(size, ext == ".safetensors" ? 1u << 20 : 16u << 20)), '\0');
    in.read(head.data(), std::streamsize(head.size()));
    f.add(head.data(), size_t(in.gcount()));
  }
  return f.hex();
}

std::string file_fingerprint(const std::filesystem::path& path) {
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_directory(path)) {
    for (const auto& e : std::filesystem::recursive_directory_iterator(path))
      if (e.is_regular_file()) files.push_back(e.path());
    std::sort(files.begin(), files.end());
  } else {
    files.push_back(path);
  }
  Fnv f;
  std::vector<char> buf(1 << 20);
  for (const auto& p : files) {
    f.add(p.filename().string());
    std::ifstream in(p, std::ios::binary);
    while (in) {
      in.read(buf.data(), std::streamsize(buf.size()));
      f.add(buf.data(), size_t(in.gcount()));
    }
  }
  return f.hex();
}

}  // namespace dvs
