// .npy reader/writer. The header is a Python dict literal; we parse exactly the subset numpy writes
// ({'descr': str, 'fortran_order': bool, 'shape': tuple of ints}) and reject anything else with a message.
#include "io/npy.hpp"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <string_view>

#include "dvs/error.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"

namespace dvs {
namespace {

constexpr uint8_t kMagic[6] = {0x93, 'N', 'U', 'M', 'P', 'Y'};
constexpr uint64_t kMaxHeaderLen = 1u << 20;  // numpy headers are ~100 bytes; anything huge is hostile

// How a stored numpy dtype maps onto an engine dtype.
struct NpyType {
  DType dtype;    // what the HostTensor holds
  size_t stored;  // bytes per element in the file
  enum Conv { copy, f64_to_f32, i64_to_i32, u16_to_i32 } conv;
};

std::optional<NpyType> npy_type(std::string_view d) {
  if (d == "<f4") return NpyType{DType::f32, 4, NpyType::copy};
  if (d == "<f2") return NpyType{DType::f16, 2, NpyType::copy};
  if (d == "<i4") return NpyType{DType::i32, 4, NpyType::copy};
  if (d == "|u1" || d == "<u1" || d == "=u1" || d == "u1") return NpyType{DType::u8, 1, NpyType::copy};
  if (d == "<f8") return NpyType{DType::f32, 8, NpyType::f64_to_f32};
  if (d == "<i8") return NpyType{DType::i32, 8, NpyType::i64_to_i32};
  if (d == "<u2") return NpyType{DType::i32, 2, NpyType::u16_to_i32};  // 16-bit depth maps; widened exactly
  return std::nullopt;
}

// A tiny cursor over the header text, with errors that carry the file name.
class HeaderParser {
 public:
  HeaderParser(std::string_view text, const std::string& name) : s_(text), name_(name) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw Error(name_ + ": malformed .npy header (" + what + ") in " + quoted_header());
  }

  void ws() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r')) ++i_;
  }
  bool peek(char c) {
    ws();
    return i_ < s_.size() && s_[i_] == c;
  }
  void expect(char c) {
    if (!peek(c)) fail(std::string("expected '") + c + "' at offset " + std::to_string(i_));
    ++i_;
  }
  bool accept(char c) {
    if (!peek(c)) return false;
    ++i_;
    return true;
  }
  bool at_end() {
    ws();
    return i_ >= s_.size();
  }

  std::string str() {
    ws();
    if (i_ >= s_.size() || (s_[i_] != '\'' && s_[i_] != '"')) fail("expected a quoted string at offset " + std::to_string(i_));
    const char q = s_[i_++];
    std::string out;
    while (i_ < s_.size() && s_[i_] != q) {
      if (s_[i_] == '\\') fail("escapes are not supported in header strings");
      out += s_[i_++];
    }
    if (i_ >= s_.size()) fail("unterminated string");
    ++i_;
    return out;
  }

  bool boolean() {
    ws();
    if (s_.substr(i_, 4) == "True") { i_ += 4; return true; }
    if (s_.substr(i_, 5) == "False") { i_ += 5; return false; }
    fail("expected True or False at offset " + std::to_string(i_));
  }

  Shape shape() {
    if (peek('[')) fail("'shape' must be a tuple");
    expect('(');
    Shape out;
    while (!accept(')')) {
      ws();
      if (i_ >= s_.size() || s_[i_] < '0' || s_[i_] > '9') {
        if (i_ < s_.size() && s_[i_] == '-') fail("negative dimension in 'shape'");
        fail("'shape' must hold non-negative integers");
      }
      uint64_t v = 0;
      while (i_ < s_.size() && s_[i_] >= '0' && s_[i_] <= '9') {
        const uint64_t digit = uint64_t(s_[i_++] - '0');
        if (v > (uint64_t(std::numeric_limits<int64_t>::max()) - digit) / 10) fail("dimension too large in 'shape'");
        v = v * 10 + digit;
      }
      if (i_ < s_.size() && s_[i_] == 'L') ++i_;  // Python 2 long suffix, still seen in old files
      out.push_back(int64_t(v));
      if (!accept(',')) {
        expect(')');
        break;
      }
    }
    return out;
  }

 private:
  std::string quoted_header() const {
    std::string h(s_.substr(0, 200));
    for (char& c : h)
      if (static_cast<unsigned char>(c) < 0x20) c = ' ';
    return "\"" + h + (s_.size() > 200 ? "...\"" : "\"");
  }

  std::string_view s_;
  const std::string& name_;
  size_t i_ = 0;
};

struct Header {
  std::string descr;
  bool fortran = false;
  Shape shape;
};

Header parse_header(std::string_view text, const std::string& name) {
  HeaderParser p(text, name);
  Header h;
  bool have_descr = false, have_fortran = false, have_shape = false;
  p.expect('{');
  while (!p.accept('}')) {
    const std::string key = p.str();
    p.expect(':');
    if (key == "descr") {
      if (p.peek('[')) p.fail("structured dtypes are not supported");
      h.descr = p.str();
      have_descr = true;
    } else if (key == "fortran_order") {
      h.fortran = p.boolean();
      have_fortran = true;
    } else if (key == "shape") {
      h.shape = p.shape();
      have_shape = true;
    } else {
      p.fail("unknown key '" + key + "'");
    }
    if (!p.accept(',')) {
      p.expect('}');
      break;
    }
  }
  if (!p.at_end()) p.fail("text after the closing '}'");
  if (!have_descr || !have_fortran || !have_shape) p.fail("it needs the keys 'descr', 'fortran_order' and 'shape'");
  return h;
}

uint64_t read_le(const uint8_t* p, int n) {
  uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

std::string descr_of(DType t) {
  switch (t) {
    case DType::f32: return "<f4";
    case DType::bf16: return "<f4";  // numpy has no bfloat16: widened exactly
    case DType::f16: return "<f2";
    case DType::i32: return "<i4";
    case DType::u8: return "|u1";
  }
  return "?";
}

std::string shape_tuple(const Shape& s) {
  std::string out = "(";
  for (size_t i = 0; i < s.size(); ++i) {
    if (i) out += ", ";
    out += std::to_string(s[i]);
  }
  if (s.size() == 1) out += ",";
  return out + ")";
}

}  // namespace

std::string cannot_create_note(const std::filesystem::path& path, int error_number) {
  const std::filesystem::path folder = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  std::error_code ec;
  if (!std::filesystem::exists(folder, ec)) return "cannot create the file: the folder " + folder.string() + " does not exist";
  if (!std::filesystem::is_directory(folder, ec)) return "cannot create the file: " + folder.string() + " is not a folder";
  return "cannot create the file in " + folder.string() + ": " + std::strerror(error_number);
}

HostTensor parse_npy(std::span<const uint8_t> b, const std::string& name) {
  if (b.size() < 10 || std::memcmp(b.data(), kMagic, 6) != 0)
    throw Error(name + ": not a .npy file (missing the \\x93NUMPY magic" +
                std::string(b.size() < 10 ? ", file is truncated)" : ")"));
  const int major = b[6], minor = b[7];
  if (!((major == 1 || major == 2 || major == 3) && minor == 0))
    throw Error(name + ": unsupported .npy format version " + std::to_string(major) + "." + std::to_string(minor) +
                " (1.0, 2.0 and 3.0 are supported)");
  const size_t prefix = major == 1 ? 10 : 12;
  if (b.size() < prefix) throw Error(name + ": .npy file is truncated inside its header length");
  const uint64_t hlen = read_le(b.data() + 8, major == 1 ? 2 : 4);
  if (hlen > kMaxHeaderLen)
    throw Error(name + ": .npy header length " + std::to_string(hlen) + " is too large (limit " +
                std::to_string(kMaxHeaderLen) + " bytes)");
  if (hlen > b.size() - prefix)
    throw Error(name + ": .npy file is truncated: header length " + std::to_string(hlen) + " runs past the end of the " +
                std::to_string(b.size()) + "-byte file");
  const std::string_view text(reinterpret_cast<const char*>(b.data() + prefix), size_t(hlen));
  const Header h = parse_header(text, name);

  if (h.fortran)
    throw Error(name + ": fortran_order arrays are not supported; save it C-contiguous (np.ascontiguousarray)");
  const auto type = npy_type(h.descr);
  if (!type)
    throw Error(name + ": unsupported .npy dtype '" + h.descr +
                "' (supported: <f4 <f2 <i4 |u1, <f8 <i8 narrowed to f32/i32, <u2 widened to i32; little-endian only)");

  // Element count with overflow checks; the data must then fit in what the file actually holds.
  uint64_t numel = 1;
  for (int64_t d : h.shape)
    if (__builtin_mul_overflow(numel, uint64_t(d), &numel))
      throw Error(name + ": .npy shape " + shape_tuple(h.shape) + " has too many elements");
  uint64_t need;
  if (__builtin_mul_overflow(numel, uint64_t(type->stored), &need))
    throw Error(name + ": .npy shape " + shape_tuple(h.shape) + " is too large");
  const uint64_t have = b.size() - prefix - hlen;
  if (have < need)
    throw Error(name + ": .npy file is truncated: shape " + shape_tuple(h.shape) + " of " + h.descr + " needs " +
                std::to_string(need) + " data bytes but only " + std::to_string(have) + " are present");
  if (have > need)
    throw Error(name + ": .npy file has " + std::to_string(have - need) + " unexpected trailing bytes after the data of shape " +
                shape_tuple(h.shape));

  HostTensor t(h.shape, type->dtype);
  const uint8_t* src = b.data() + prefix + hlen;
  switch (type->conv) {
    case NpyType::copy:
      if (need) std::memcpy(t.data.data(), src, size_t(need));
      break;
    case NpyType::f64_to_f32:
      for (uint64_t i = 0; i < numel; ++i) {
        double v;
        std::memcpy(&v, src + 8 * i, 8);
        const float f = float(v);  // round to nearest; out-of-range becomes +-Inf, NaN stays NaN
        std::memcpy(t.data.data() + 4 * i, &f, 4);
      }
      break;
    case NpyType::u16_to_i32:
      for (uint64_t i = 0; i < numel; ++i) {
        uint16_t v;
        std::memcpy(&v, src + 2 * i, 2);
        const int32_t w = int32_t(v);
        std::memcpy(t.data.data() + 4 * i, &w, 4);
      }
      break;
    case NpyType::i64_to_i32:
      for (uint64_t i = 0; i < numel; ++i) {
        int64_t v;
        std::memcpy(&v, src + 8 * i, 8);
        if (v < std::numeric_limits<int32_t>::min() || v > std::numeric_limits<int32_t>::max())
          throw Error(name + ": int64 value " + std::to_string(v) + " at flat index " + std::to_string(i) +
                      " does not fit in int32");
        const int32_t w = int32_t(v);
        std::memcpy(t.data.data() + 4 * i, &w, 4);
      }
      break;
  }
  return t;
}

HostTensor read_npy(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw Error(name + ": no such .npy file" + (std::filesystem::exists(path, ec) ? " (not a regular file)" : ""));
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw Error(name + ": cannot read size: " + ec.message());
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(name + ": cannot open for reading: " + std::strerror(errno));
  std::vector<uint8_t> bytes(size);
  if (size && !in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size)))
    throw Error(name + ": read failed");
  return parse_npy(bytes, name);
}

std::vector<uint8_t> encode_npy(const HostTensor& t) {
  for (int64_t d : t.shape)
    if (d < 0) throw Error("write_npy: negative dimension in shape " + shape_str(t.shape));
  uint64_t numel = 1;
  for (int64_t d : t.shape)
    if (__builtin_mul_overflow(numel, uint64_t(d), &numel)) throw Error("write_npy: shape too large");
  if (t.data.size() != numel * dtype_size(t.dtype))
    throw Error("write_npy: tensor of shape " + shape_str(t.shape) + " and dtype " + dtype_name(t.dtype) + " holds " +
                std::to_string(t.data.size()) + " bytes, expected " + std::to_string(numel * dtype_size(t.dtype)));

  std::string dict =
      "{'descr': '" + descr_of(t.dtype) + "', 'fortran_order': False, 'shape': " + shape_tuple(t.shape) + ", }";
  // Like numpy: pad with spaces and end in '\n' so the data starts on a 64-byte boundary.
  size_t prefix = 10;
  size_t total = prefix + dict.size() + 1;
  if (total + (64 - total % 64) % 64 - prefix > 0xffff) {
    prefix = 12;  // version 2.0: 4-byte header length
    total = prefix + dict.size() + 1;
  }
  dict.append((64 - total % 64) % 64, ' ');
  dict += '\n';
  const size_t hlen = dict.size();

  const size_t data_bytes = t.dtype == DType::bf16 ? size_t(numel) * 4 : t.data.size();
  std::vector<uint8_t> out(prefix + hlen + data_bytes);
  std::memcpy(out.data(), kMagic, 6);
  out[6] = prefix == 10 ? 1 : 2;
  out[7] = 0;
  for (size_t i = 0; i < prefix - 8; ++i) out[8 + i] = uint8_t(hlen >> (8 * i));
  std::memcpy(out.data() + prefix, dict.data(), hlen);
  uint8_t* dst = out.data() + prefix + hlen;
  if (t.dtype == DType::bf16) {
    for (uint64_t i = 0; i < numel; ++i) {
      uint16_t v;
      std::memcpy(&v, t.data.data() + 2 * i, 2);
      const float f = bf16_to_f32(v);
      std::memcpy(dst + 4 * i, &f, 4);
    }
  } else if (data_bytes) {
    std::memcpy(dst, t.data.data(), data_bytes);
  }
  return out;
}

void write_npy(const std::filesystem::path& path, const HostTensor& t) {
  const std::vector<uint8_t> bytes = encode_npy(t);
  // Unique temp name in the same directory, so the final rename is atomic on the same filesystem.
  static std::atomic<unsigned> counter{0};
  std::filesystem::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  const std::string name = path.string();
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw Error(name + ": " + cannot_create_note(path, errno));
  bool wrote = bytes.empty() || std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  int werr = errno;
  if (const int injected = faults::write_error(path); injected && wrote) wrote = false, werr = injected;
  const bool closed = std::fclose(f) == 0;
  std::error_code ec;
  if (!wrote || !closed) {
    std::filesystem::remove(tmp, ec);
    const int e = wrote ? errno : werr;
    throw Error(name + ": write failed: " + write_error_note(e, path.parent_path()) + " (nothing was written)");
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    const std::string why = ec.message();
    std::filesystem::remove(tmp, ec);
    throw Error(name + ": cannot move the finished file into place: " + why);
  }
}

}  // namespace dvs
