// Safetensors reader: POSIX mmap plus a header validator that treats the file as untrusted input.
#include "io/safetensors.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>

#include "dvs/error.hpp"
#include "io/json_file.hpp"

namespace dvs {
namespace {

using nlohmann::json;

constexpr uint64_t kMaxHeaderLen = 100ull << 20;  // the reference implementation's limit as well
constexpr int kMaxJsonDepth = 64;                 // a valid header needs 3 levels

struct DTypeRow {
  const char* name;
  size_t size;
};
constexpr DTypeRow kDTypes[] = {
    {"F64", 8}, {"F32", 4}, {"F16", 2}, {"BF16", 2}, {"I64", 8}, {"I32", 4}, {"I16", 2}, {"I8", 1},
    {"U8", 1},  {"BOOL", 1}, {"F8_E4M3", 1}, {"F8_E5M2", 1}, {"U16", 2}, {"U32", 4}, {"U64", 8},
};

std::string span_str(uint64_t b, uint64_t e) {
  std::string out = "[";  // built by appends: GCC 12 warns falsely (-Wrestrict) on "[" + std::string
  out += std::to_string(b);
  out += ",";
  out += std::to_string(e);
  return out + "]";
}

// Offset of the first byte that breaks UTF-8 well-formedness (RFC 3629: no overlongs, no surrogates,
// nothing above U+10FFFF), or npos.
size_t find_invalid_utf8(std::string_view s) {
  size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    size_t len;
    unsigned char lo = 0x80, hi = 0xbf;  // allowed range of the second byte
    if (c < 0x80) { ++i; continue; }
    if (c >= 0xc2 && c <= 0xdf) len = 2;
    else if (c == 0xe0) { len = 3; lo = 0xa0; }
    else if (c == 0xed) { len = 3; hi = 0x9f; }
    else if (c >= 0xe1 && c <= 0xef) len = 3;
    else if (c == 0xf0) { len = 4; lo = 0x90; }
    else if (c == 0xf4) { len = 4; hi = 0x8f; }
    else if (c >= 0xf1 && c <= 0xf3) len = 4;
    else return i;
    if (i + len > s.size()) return i;
    const auto c1 = static_cast<unsigned char>(s[i + 1]);
    if (c1 < lo || c1 > hi) return i;
    for (size_t k = 2; k < len; ++k) {
      const auto ck = static_cast<unsigned char>(s[i + k]);
      if (ck < 0x80 || ck > 0xbf) return i;
    }
    i += len;
  }
  return std::string_view::npos;
}

}  // namespace

size_t safetensors_dtype_size(std::string_view name) {
  for (const auto& r : kDTypes)
    if (name == r.name) return r.size;
  return 0;
}

std::optional<DType> safetensors_engine_dtype(std::string_view name) {
  if (name == "F32") return DType::f32;
  if (name == "F16") return DType::f16;
  if (name == "BF16") return DType::bf16;
  if (name == "I32") return DType::i32;
  if (name == "U8") return DType::u8;
  return std::nullopt;
}

const char* safetensors_dtype_name(DType t) {
  switch (t) {
    case DType::f32: return "F32";
    case DType::f16: return "F16";
    case DType::bf16: return "BF16";
    case DType::i32: return "I32";
    case DType::u8: return "U8";
  }
  return "?";
}

SafetensorsFile SafetensorsFile::open(const std::filesystem::path& path) {
  SafetensorsFile f;
  f.path_ = path;
  const std::string name = path.string();
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    throw Error(name + ": cannot open safetensors file: " + std::strerror(errno) +
                (errno == ENOENT ? " (check the path, or download the weights)" : ""));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw Error(name + ": not a regular file");
  }
  f.size_ = uint64_t(st.st_size);
  if (f.size_ < 8) {
    ::close(fd);
    throw Error(name + ": file is truncated: " + std::to_string(f.size_) +
                " bytes, a safetensors file starts with an 8-byte header length");
  }
  void* m = ::mmap(nullptr, size_t(f.size_), PROT_READ, MAP_PRIVATE, fd, 0);
  const int map_errno = errno;
  ::close(fd);  // the mapping keeps the file alive
  if (m == MAP_FAILED) throw Error(name + ": mmap failed: " + std::strerror(map_errno));
  f.map_ = static_cast<const uint8_t*>(m);
  f.parse_header();  // on error, f's destructor unmaps
  return f;
}

SafetensorsFile::SafetensorsFile(SafetensorsFile&& o) noexcept { *this = std::move(o); }

SafetensorsFile& SafetensorsFile::operator=(SafetensorsFile&& o) noexcept {
  if (this != &o) {
    if (map_) ::munmap(const_cast<uint8_t*>(map_), size_t(size_));
    path_ = std::move(o.path_);
    map_ = std::exchange(o.map_, nullptr);
    size_ = std::exchange(o.size_, 0);
    header_len_ = std::exchange(o.header_len_, 0);
    tensors_ = std::move(o.tensors_);
    index_ = std::move(o.index_);
    metadata_ = std::move(o.metadata_);
  }
  return *this;
}

SafetensorsFile::~SafetensorsFile() {
  if (map_) ::munmap(const_cast<uint8_t*>(map_), size_t(size_));
}

void SafetensorsFile::parse_header() {
  const std::string file = path_.string();
  auto fail = [&](const std::string& what) -> void { throw Error(file + ": " + what); };
  auto fail_t = [&](const std::string& tensor, const std::string& what) -> void {
    throw Error(file + ": tensor '" + tensor + "': " + what);
  };

  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | map_[i];
  if (n == 0) fail("header length is 0; a safetensors header is a JSON object of at least 2 bytes");
  if (n > kMaxHeaderLen)
    fail("header length " + std::to_string(n) + " exceeds the " + std::to_string(kMaxHeaderLen) +
         "-byte limit (corrupt file, or not a safetensors file)");
  if (n > size_ - 8)
    fail("header length " + std::to_string(n) + " runs past the end of the file (" + std::to_string(size_) +
         " bytes); the file is truncated or not a safetensors file");
  header_len_ = n;

  const std::string_view text(reinterpret_cast<const char*>(map_ + 8), size_t(n));
  if (const size_t bad = find_invalid_utf8(text); bad != std::string_view::npos)
    fail("header is not valid UTF-8 (bad byte at header offset " + std::to_string(bad) + ")");
  if (json_nests_deeper_than(text, kMaxJsonDepth))
    fail("header JSON nests deeper than " + std::to_string(kMaxJsonDepth) + " levels; refusing to parse it");

  // Duplicate keys: nlohmann keeps the last silently, so watch keys per object while parsing.
  std::vector<std::set<std::string>> open_objects;
  std::string duplicate;
  auto watch = [&](int, json::parse_event_t ev, json& parsed) {
    if (ev == json::parse_event_t::object_start) open_objects.emplace_back();
    else if (ev == json::parse_event_t::object_end && !open_objects.empty()) open_objects.pop_back();
    else if (ev == json::parse_event_t::key && !open_objects.empty() && parsed.is_string() &&
             !open_objects.back().insert(parsed.get<std::string>()).second && duplicate.empty())
      duplicate = parsed.get<std::string>();
    return true;
  };
  json h;
  try {
    h = json::parse(text.begin(), text.end(), watch);
  } catch (const json::exception& e) {
    fail(std::string("header is not valid JSON: ") + e.what());
  }
  if (!duplicate.empty()) fail("header JSON has the key '" + duplicate + "' twice");
  if (!h.is_object()) fail("header JSON is not an object");

  const uint64_t data_size = size_ - 8 - n;
  for (const auto& [key, v] : h.items()) {
    if (key == "__metadata__") {
      if (!v.is_object()) fail("'__metadata__' is not an object");
      for (const auto& [mk, mv] : v.items()) {
        if (!mv.is_string()) fail("'__metadata__' entry '" + mk + "' is not a string");
        metadata_[mk] = mv.get<std::string>();
      }
      continue;
    }
    if (key.empty()) fail("a tensor has an empty name");
    if (!v.is_object()) fail_t(key, "entry is not an object");
    TensorInfo t;
    t.name = key;

    const auto dt = v.find("dtype");
    if (dt == v.end() || !dt->is_string()) fail_t(key, "missing or non-string 'dtype'");
    t.dtype_name = dt->get<std::string>();
    t.elem_size = safetensors_dtype_size(t.dtype_name);
    if (t.elem_size == 0)
      fail_t(key, "unknown dtype '" + t.dtype_name +
                      "' (known: F64 F32 F16 BF16 I64 I32 I16 I8 U8 BOOL F8_E4M3 F8_E5M2 U16 U32 U64)");
    t.dtype = safetensors_engine_dtype(t.dtype_name);

    const auto sh = v.find("shape");
    if (sh == v.end() || !sh->is_array()) fail_t(key, "missing 'shape' or it is not an array");
    uint64_t numel = 1;
    bool overflow = false;
    for (const auto& d : *sh) {
      if (d.is_number_integer() && !d.is_number_unsigned())
        fail_t(key, "negative dimension " + d.dump() + " in shape " + sh->dump());
      if (!d.is_number_unsigned()) fail_t(key, "shape " + sh->dump() + " holds a non-integer dimension " + d.dump());
      const uint64_t u = d.get<uint64_t>();
      if (u > uint64_t(std::numeric_limits<int64_t>::max()))
        fail_t(key, "dimension " + d.dump() + " in shape " + sh->dump() + " is too large");
      t.shape.push_back(int64_t(u));
      overflow = overflow || __builtin_mul_overflow(numel, u, &numel);
    }
    uint64_t need = 0;
    if (overflow || __builtin_mul_overflow(numel, uint64_t(t.elem_size), &need))
      fail_t(key, "shape " + shape_list(t.shape) + " × " + t.dtype_name + " overflows 64 bits (corrupt header)");
    t.numel = numel;

    const auto off = v.find("data_offsets");
    if (off == v.end() || !off->is_array() || off->size() != 2 || !(*off)[0].is_number_unsigned() ||
        !(*off)[1].is_number_unsigned())
      fail_t(key, "'data_offsets' must be [begin, end] with non-negative integers, got " +
                      (off == v.end() ? std::string("nothing") : off->dump()));
    t.begin = (*off)[0].get<uint64_t>();
    t.end = (*off)[1].get<uint64_t>();
    if (t.begin > t.end) fail_t(key, "data_offsets " + span_str(t.begin, t.end) + ": begin is after end");
    if (t.end > data_size)
      fail_t(key, "data_offsets " + span_str(t.begin, t.end) + " run past the end of the data section (" +
                      std::to_string(data_size) + " bytes); the file is truncated or corrupt");
    if (t.end - t.begin != need)
      fail_t(key, "data_offsets " + span_str(t.begin, t.end) + " span " + std::to_string(t.end - t.begin) +
                      " bytes but shape " + shape_list(t.shape) + " × " + t.dtype_name + " needs " +
                      std::to_string(need));
    tensors_.push_back(std::move(t));
  }

  // No two tensors may share a byte: sort spans by start and compare with the furthest end so far.
  std::vector<const TensorInfo*> by_offset;
  for (const auto& t : tensors_)
    if (t.end > t.begin) by_offset.push_back(&t);
  std::sort(by_offset.begin(), by_offset.end(),
            [](const TensorInfo* a, const TensorInfo* b) { return a->begin < b->begin; });
  const TensorInfo* furthest = nullptr;
  for (const TensorInfo* t : by_offset) {
    if (furthest && t->begin < furthest->end)
      fail("tensors '" + furthest->name + "' " + span_str(furthest->begin, furthest->end) + " and '" + t->name +
           "' " + span_str(t->begin, t->end) + " overlap in the data section");
    if (!furthest || t->end > furthest->end) furthest = t;
  }

  // json objects iterate in key order, so tensors_ is already sorted by name.
  for (size_t i = 0; i < tensors_.size(); ++i) index_.emplace(tensors_[i].name, i);
}

const TensorInfo* SafetensorsFile::find(std::string_view name) const {
  const auto it = index_.find(std::string(name));
  return it == index_.end() ? nullptr : &tensors_[it->second];
}

std::span<const uint8_t> SafetensorsFile::bytes(const TensorInfo& t) const {
  return {map_ + 8 + header_len_ + t.begin, size_t(t.nbytes())};
}

std::vector<const WeightEntry*> SafetensorsFile::entries() const { return entry_list(tensors_); }

TensorBytes SafetensorsFile::bytes(const WeightEntry& entry) const {
  return TensorBytes(bytes(own_entry(find(entry.name), entry)));
}

HostTensor SafetensorsFile::load(const WeightEntry& entry) const {
  const TensorInfo& t = own_entry(find(entry.name), entry);
  if (!t.dtype)
    throw Error(path_.string() + ": tensor '" + t.name + "': dtype " + t.dtype_name +
                " is not usable by the engine (F32, F16, BF16, I32, U8); convert it with dvs-weights");
  HostTensor out(t.shape, *t.dtype);
  const auto b = bytes(t);
  if (!b.empty()) std::memcpy(out.data.data(), b.data(), b.size());
  return out;
}

}  // namespace dvs
