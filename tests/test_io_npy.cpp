// .npy read/write and the HostTensor 16-bit float conversions.
#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "dvs/error.hpp"
#include "io/host_tensor.hpp"
#include "io/npy.hpp"

namespace fs = std::filesystem;
using dvs::DType;
using dvs::HostTensor;

using dvs::test::golden_path;
using dvs::test::TempDir;

namespace {

std::vector<uint8_t> file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void put_bytes(const fs::path& p, const std::vector<uint8_t>& b) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

// A .npy file with a hand-written header (any version) and raw data.
std::vector<uint8_t> make_npy(const std::string& dict, const std::vector<uint8_t>& data, int major = 1) {
  std::string h = dict;
  const size_t prefix = major == 1 ? 10 : 12;
  while ((prefix + h.size() + 1) % 64) h += ' ';
  h += '\n';
  std::vector<uint8_t> out = {0x93, 'N', 'U', 'M', 'P', 'Y', uint8_t(major), 0};
  for (size_t i = 0; i < prefix - 8; ++i) out.push_back(uint8_t(h.size() >> (8 * i)));
  out.insert(out.end(), h.begin(), h.end());
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

template <class T>
std::vector<uint8_t> raw(const std::vector<T>& v) {
  std::vector<uint8_t> b(v.size() * sizeof(T));
  if (!b.empty()) std::memcpy(b.data(), v.data(), b.size());
  return b;
}

using dvs::test::expect_error;

// Reference rounding: the nearest representable value by exhaustive search over the non-negative finite
// 16-bit patterns (which increase monotonically), ties to the even pattern.
uint16_t nearest16(float x, float (*widen)(uint16_t), uint16_t max_finite, uint16_t inf) {
  const uint16_t sign = std::signbit(x) ? 0x8000 : 0;
  const double a = std::fabs(double(x));
  uint16_t lo = 0, hi = max_finite;
  if (a >= double(widen(max_finite))) {
    // Above the largest finite value: round to it or to Inf as if the next step existed.
    const double step = double(widen(max_finite)) - double(widen(uint16_t(max_finite - 1)));
    const double mid = double(widen(max_finite)) + step / 2;
    return uint16_t(sign | (a < mid ? max_finite : inf));
  }
  while (hi - lo > 1) {
    const uint16_t m = uint16_t((lo + hi) / 2);
    if (double(widen(m)) <= a) lo = m;
    else hi = m;
  }
  const double dl = a - double(widen(lo)), dh = double(widen(hi)) - a;
  uint16_t r = dl < dh ? lo : dh < dl ? hi : ((lo & 1) ? hi : lo);
  if (a == double(widen(hi))) r = hi;
  return uint16_t(sign | r);
}

}  // namespace

// ---- HostTensor conversions ---------------------------------------------------------------------------------

TEST(IoHostTensor, ShapeStrAndFromF32) {
  EXPECT_EQ(dvs::shape_str({1, 3, 8, 8}), "1x3x8x8");
  EXPECT_EQ(dvs::shape_str({}), "scalar");
  const std::vector<float> v = {1, 2, 3, 4, 5, 6};
  const HostTensor t = HostTensor::from_f32({2, 3}, v);
  EXPECT_EQ(t.dtype, DType::f32);
  EXPECT_EQ(t.bytes(), 24u);
  EXPECT_EQ(t.to_f32(), v);
  EXPECT_THROW(HostTensor::from_f32({4}, v), dvs::Error);
  EXPECT_THROW(HostTensor::from_f32({-1, -6}, v), dvs::Error);
}

TEST(IoHostTensor, Bf16EveryPatternSurvivesARoundTrip) {
  for (uint32_t b = 0; b <= 0xffff; ++b) {
    const float f = dvs::bf16_to_f32(uint16_t(b));
    if (std::isnan(f)) {
      EXPECT_TRUE(std::isnan(dvs::bf16_to_f32(dvs::f32_to_bf16(f)))) << std::hex << b;
      EXPECT_EQ(dvs::f32_to_bf16(f) & 0x8000, b & 0x8000) << "sign of NaN kept";
    } else {
      EXPECT_EQ(dvs::f32_to_bf16(f), b) << std::hex << b;
    }
  }
}

TEST(IoHostTensor, Bf16RoundsToNearestEven) {
  EXPECT_EQ(dvs::f32_to_bf16(1.0f + std::ldexp(1.0f, -8)), 0x3f80);      // tie -> even (down)
  EXPECT_EQ(dvs::f32_to_bf16(1.0f + 3 * std::ldexp(1.0f, -8)), 0x3f82);  // tie -> even (up)
  EXPECT_EQ(dvs::f32_to_bf16(std::nextafter(1.0f + std::ldexp(1.0f, -8), 2.0f)), 0x3f81);
  EXPECT_EQ(dvs::f32_to_bf16(-1.0f - std::ldexp(1.0f, -8)), 0xbf80);
  EXPECT_EQ(dvs::f32_to_bf16(std::numeric_limits<float>::max()), 0x7f80);  // rounds up to Inf
  EXPECT_EQ(dvs::f32_to_bf16(std::numeric_limits<float>::infinity()), 0x7f80);
  EXPECT_EQ(dvs::f32_to_bf16(-0.0f), 0x8000);
  // A NaN whose payload lives only in the low 16 bits must not become Inf.
  EXPECT_TRUE(std::isnan(dvs::bf16_to_f32(dvs::f32_to_bf16(std::bit_cast<float>(0x7f800001u)))));
  EXPECT_TRUE(std::isnan(dvs::bf16_to_f32(dvs::f32_to_bf16(std::bit_cast<float>(0xff800001u)))));

  std::mt19937 rng(1);
  std::uniform_int_distribution<uint32_t> bits;
  for (int i = 0; i < 20000; ++i) {
    const float f = std::bit_cast<float>(bits(rng));
    if (!std::isfinite(f)) continue;
    EXPECT_EQ(dvs::f32_to_bf16(f), nearest16(f, dvs::bf16_to_f32, 0x7f7f, 0x7f80)) << f;
  }
}

TEST(IoHostTensor, F16EveryPatternSurvivesARoundTrip) {
  for (uint32_t b = 0; b <= 0xffff; ++b) {
    const float f = dvs::f16_to_f32(uint16_t(b));
    if (std::isnan(f)) EXPECT_TRUE(std::isnan(dvs::f16_to_f32(dvs::f32_to_f16(f)))) << std::hex << b;
    else EXPECT_EQ(dvs::f32_to_f16(f), b) << std::hex << b;
  }
  EXPECT_EQ(dvs::f16_to_f32(0x0001), std::ldexp(1.0f, -24));
  EXPECT_EQ(dvs::f16_to_f32(0x7bff), 65504.0f);
  EXPECT_EQ(dvs::f16_to_f32(0xc000), -2.0f);
}

TEST(IoHostTensor, F16RoundsToNearestEven) {
  EXPECT_EQ(dvs::f32_to_f16(65519.0f), 0x7bff);
  EXPECT_EQ(dvs::f32_to_f16(65520.0f), 0x7c00);  // tie at the top rounds to Inf
  EXPECT_EQ(dvs::f32_to_f16(-1e10f), 0xfc00);
  EXPECT_EQ(dvs::f32_to_f16(std::ldexp(1.0f, -25)), 0x0000);         // tie -> even zero
  EXPECT_EQ(dvs::f32_to_f16(std::ldexp(1.5f, -25)), 0x0001);
  EXPECT_EQ(dvs::f32_to_f16(std::ldexp(2.5f, -24)), 0x0002);         // subnormal tie -> even
  EXPECT_EQ(dvs::f32_to_f16(std::ldexp(3.5f, -24)), 0x0004);
  EXPECT_EQ(dvs::f32_to_f16(1.0f + std::ldexp(1.0f, -11)), 0x3c00);  // tie -> even
  EXPECT_EQ(dvs::f32_to_f16(std::ldexp(1023.5f, -24)), 0x0400);      // carries into the smallest normal
  EXPECT_TRUE(std::isnan(dvs::f16_to_f32(dvs::f32_to_f16(std::bit_cast<float>(0x7f800001u)))));

  std::mt19937 rng(2);
  std::uniform_int_distribution<uint32_t> bits;
  std::uniform_real_distribution<float> small(-70000.0f, 70000.0f);
  for (int i = 0; i < 20000; ++i) {
    float f = (i & 1) ? small(rng) : std::bit_cast<float>(bits(rng));
    if (!std::isfinite(f)) continue;
    if (i % 4 == 0) f = std::ldexp(f, -std::ilogb(f) - 14 - int(i % 13));  // land in the subnormal range
    EXPECT_EQ(dvs::f32_to_f16(f), nearest16(f, dvs::f16_to_f32, 0x7bff, 0x7c00)) << f;
  }
}

TEST(IoHostTensor, ToF32WidensEveryDtype) {
  HostTensor h({3}, DType::f16);
  const uint16_t hv[] = {0x3c00, 0xc000, 0x7c00};
  std::memcpy(h.data.data(), hv, 6);
  EXPECT_EQ(h.to_f32(), (std::vector<float>{1.0f, -2.0f, std::numeric_limits<float>::infinity()}));
  HostTensor b({2}, DType::bf16);
  const uint16_t bv[] = {0x3f80, 0x4040};
  std::memcpy(b.data.data(), bv, 4);
  EXPECT_EQ(b.to_f32(), (std::vector<float>{1.0f, 3.0f}));
  HostTensor i({2}, DType::i32);
  const int32_t iv[] = {-7, 1 << 20};
  std::memcpy(i.data.data(), iv, 8);
  EXPECT_EQ(i.to_f32(), (std::vector<float>{-7.0f, float(1 << 20)}));
  HostTensor u({2}, DType::u8);
  u.data = {0, 255};
  EXPECT_EQ(u.to_f32(), (std::vector<float>{0.0f, 255.0f}));
}

// ---- .npy round trips ---------------------------------------------------------------------------------------

TEST(IoNpy, RoundTripsEveryDtypeAndOddShapes) {
  TempDir dir;
  const std::vector<dvs::Shape> shapes = {{}, {0}, {3, 0, 2}, {1}, {7}, {2, 3, 5}, {1, 1, 1, 1, 1, 1, 1}, {13, 1, 3}};
  std::mt19937 rng(3);
  for (DType dt : {DType::f32, DType::f16, DType::bf16, DType::i32, DType::u8}) {
    for (const auto& shape : shapes) {
      HostTensor t(shape, dt);
      for (auto& byte : t.data) byte = uint8_t(rng());
      if (dt == DType::f16 || dt == DType::bf16)  // keep NaNs out so values compare with ==
        for (size_t k = 1; k < t.data.size(); k += 2) t.data[k] &= 0x3f;
      const fs::path p = dir / ("t_" + std::string(dvs::dtype_name(dt)) + "_" + dvs::shape_str(shape) + ".npy");
      dvs::write_npy(p, t);
      const HostTensor r = dvs::read_npy(p);
      EXPECT_EQ(r.shape, shape);
      if (dt == DType::bf16) {  // numpy has no bf16: stored as exact f32
        EXPECT_EQ(r.dtype, DType::f32);
        EXPECT_EQ(r.to_f32(), t.to_f32());
      } else {
        EXPECT_EQ(r.dtype, dt);
        EXPECT_EQ(r.data, t.data);
      }
      // numpy's layout: the data starts on a 64-byte boundary.
      const auto bytes = file_bytes(p);
      EXPECT_EQ((bytes.size() - r.bytes()) % 64, 0u);
    }
  }
  // Nothing but the finished files: no temp files left behind.
  for (const auto& e : fs::directory_iterator(dir.path)) EXPECT_EQ(e.path().extension(), ".npy") << e.path();
}

TEST(IoNpy, HeaderMatchesNumpyByteForByte) {
  // The pack's files were written by numpy; re-encoding what we read must give the same bytes.
  for (const char* rel : {"t5/masked_last_hidden_state.npy", "transformer/rope_cos.npy", "e2e/sampling_timesteps.npy",
                          "transformer/timestep_999.npy"}) {
    const fs::path p = golden_path() / rel;
    EXPECT_EQ(dvs::encode_npy(dvs::read_npy(p)), file_bytes(p)) << p;
  }
}

TEST(IoNpy, LongHeaderUsesVersion2) {
  TempDir dir;
  HostTensor t(dvs::Shape(30000, 1), DType::u8);
  t.data = {42};
  dvs::write_npy(dir / "long.npy", t);
  const auto b = file_bytes(dir / "long.npy");
  EXPECT_EQ(b[6], 2);
  const HostTensor r = dvs::read_npy(dir / "long.npy");
  EXPECT_EQ(r.shape.size(), 30000u);
  EXPECT_EQ(r.data, t.data);
}

TEST(IoNpy, ReadsVersions2And3AndWideTypes) {
  TempDir dir;
  const std::vector<float> f = {1.5f, -2.0f, 3.25f};
  put_bytes(dir / "v2.npy", make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (3,), }", raw(f), 2));
  put_bytes(dir / "v3.npy", make_npy("{\"descr\": \"<f4\", \"fortran_order\": False, \"shape\": (3,)}", raw(f), 3));
  EXPECT_EQ(dvs::read_npy(dir / "v2.npy").to_f32(), f);
  EXPECT_EQ(dvs::read_npy(dir / "v3.npy").to_f32(), f);

  const std::vector<double> d = {0.1, -1e300, 2.5, std::numeric_limits<double>::quiet_NaN()};
  put_bytes(dir / "f8.npy", make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }", raw(d)));
  const HostTensor rd = dvs::read_npy(dir / "f8.npy");
  EXPECT_EQ(rd.dtype, DType::f32);
  EXPECT_EQ(rd.shape, (dvs::Shape{2, 2}));
  const auto vd = rd.to_f32();
  EXPECT_EQ(vd[0], 0.1f);
  EXPECT_EQ(vd[1], -std::numeric_limits<float>::infinity());
  EXPECT_EQ(vd[2], 2.5f);
  EXPECT_TRUE(std::isnan(vd[3]));

  const std::vector<int64_t> ok = {0, -5, 2147483647, -2147483648LL};
  put_bytes(dir / "i8.npy", make_npy("{'descr': '<i8', 'fortran_order': False, 'shape': (4,), }", raw(ok)));
  const HostTensor ri = dvs::read_npy(dir / "i8.npy");
  EXPECT_EQ(ri.dtype, DType::i32);
  EXPECT_EQ(ri.as<int32_t>()[2], 2147483647);
  EXPECT_EQ(ri.as<int32_t>()[3], -2147483647 - 1);

  const std::vector<int64_t> big = {1, 2147483648LL};
  put_bytes(dir / "i8big.npy", make_npy("{'descr': '<i8', 'fortran_order': False, 'shape': (2,), }", raw(big)));
  expect_error([&] { dvs::read_npy(dir / "i8big.npy"); }, "i8big.npy", "int32");
}

TEST(IoNpy, RejectsMalformedFiles) {
  TempDir dir;
  const std::vector<float> f6(6, 1.0f);
  const std::string ok = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }";
  struct Case {
    std::string file, word;
    std::vector<uint8_t> bytes;
  };
  auto good = make_npy(ok, raw(f6));
  std::vector<Case> cases = {
      {"fortran.npy", "fortran_order", make_npy("{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3), }", raw(f6))},
      {"bigendian.npy", "'>f4'", make_npy("{'descr': '>f4', 'fortran_order': False, 'shape': (2, 3), }", raw(f6))},
      {"complex.npy", "unsupported .npy dtype", make_npy("{'descr': '<c8', 'fortran_order': False, 'shape': (3,), }", raw(f6))},
      {"structured.npy", "structured", make_npy("{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (6,), }", raw(f6))},
      {"magic.npy", "magic", {'N', 'O', 'T', 'N', 'P', 'Y', 1, 0, 0, 0, 0, 0}},
      {"tiny.npy", "truncated", {0x93, 'N', 'U'}},
      {"empty.npy", "truncated", {}},
      {"version.npy", "version 4.0", [&] { auto b = good; b[6] = 4; return b; }()},
      {"shortdata.npy", "truncated", [&] { auto b = good; b.resize(b.size() - 1); return b; }()},
      {"trailing.npy", "trailing", [&] { auto b = good; b.push_back(0); return b; }()},
      {"hlen.npy", "past the end", [&] { auto b = good; b.resize(40); return b; }()},
      {"negative.npy", "negative", make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (-2, 3), }", raw(f6))},
      {"overflow.npy", "too many elements",
       make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296, 16), }", raw(f6))},
      {"hugedim.npy", "too large",
       make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999999,), }", raw(f6))},
      {"hugedata.npy", "truncated",
       make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (1000000000, 1000), }", raw(f6))},
      {"unknownkey.npy", "unknown key", make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (6,), 'x': 1}", raw(f6))},
      {"missingkey.npy", "needs the keys", make_npy("{'descr': '<f4', 'shape': (6,), }", raw(f6))},
      {"list.npy", "tuple", make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': [6], }", raw(f6))},
      {"garbage.npy", "malformed", make_npy("{'descr' '<f4'}", raw(f6))},
  };
  for (const auto& c : cases) {
    put_bytes(dir / c.file, c.bytes);
    SCOPED_TRACE(c.file);
    expect_error([&] { dvs::read_npy(dir / c.file); }, c.file, c.word);
  }
  expect_error([&] { dvs::read_npy(dir / "absent.npy"); }, "absent.npy", "no such");
}

TEST(IoNpy, FailedWritesLeaveNoFile) {
  TempDir dir;
  HostTensor bad({2, 2}, DType::f32);
  bad.data.resize(3);  // inconsistent with the shape
  EXPECT_THROW(dvs::write_npy(dir / "bad.npy", bad), dvs::Error);
  EXPECT_THROW(dvs::write_npy(dir / "missing_dir" / "x.npy", HostTensor({1}, DType::f32)), dvs::Error);
  EXPECT_TRUE(fs::is_empty(dir.path));
  // Overwriting replaces the old file whole.
  dvs::write_npy(dir / "x.npy", HostTensor::from_f32({1}, std::vector<float>{1.0f}));
  dvs::write_npy(dir / "x.npy", HostTensor::from_f32({2}, std::vector<float>{2.0f, 3.0f}));
  EXPECT_EQ(dvs::read_npy(dir / "x.npy").to_f32(), (std::vector<float>{2.0f, 3.0f}));
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir.path)) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
}

// ---- the golden pack's files ----------------------------------------------------------------------------------

TEST(IoNpy, ReadsEveryPackFileWithItsRecordedShapeAndStats) {
  const fs::path root = golden_path();
  std::ifstream in(root / "cases.json");
  ASSERT_TRUE(in) << "golden pack not found at " << root << " (set DVS_GOLDEN_DIR)";
  const nlohmann::json cases = nlohmann::json::parse(in)["cases"];
  size_t checked = 0, f64_checked = 0;
  for (const auto& c : cases)
    for (const auto& f : c["files"]) {
      if (!f.contains("dtype") || f["dtype"] != "float32") continue;
      SCOPED_TRACE(f["file"].get<std::string>());
      const HostTensor t = dvs::read_npy(root / f["file"].get<std::string>());
      EXPECT_EQ(t.dtype, DType::f32);
      EXPECT_EQ(t.shape, f["shape"].get<dvs::Shape>());
      const auto v = t.to_f32();
      if (!v.empty()) {
        const auto [mn, mx] = std::minmax_element(v.begin(), v.end());
        EXPECT_EQ(double(*mn), f["stats"]["min"].get<double>());
        EXPECT_EQ(double(*mx), f["stats"]["max"].get<double>());
      }
      if (f.contains("float64_copy")) {
        // The f64 copy narrowed to f32 agrees with the f32 file to f32 rounding.
        const HostTensor d = dvs::read_npy(root / f["float64_copy"].get<std::string>());
        EXPECT_EQ(d.shape, t.shape);
        const auto w = d.to_f32();
        for (size_t i = 0; i < v.size(); ++i) EXPECT_NEAR(w[i], v[i], std::fabs(v[i]) * 1.2e-7 + 1e-30) << i;
        ++f64_checked;
      }
      ++checked;
    }
  EXPECT_GT(checked, 100u);
  EXPECT_GT(f64_checked, 0u);
}
