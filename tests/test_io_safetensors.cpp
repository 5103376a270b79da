// Safetensors reader: valid files, the golden pack's weights against their schemas, and crafted corrupt
// files that must each be rejected with a dvs::Error naming the file and the problem.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "dvs/error.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "io/safetensors.hpp"

namespace fs = std::filesystem;
using dvs::DType;
using nlohmann::json;

using dvs::test::golden_path;
using dvs::test::TempDir;

namespace {

void put_bytes(const fs::path& p, const std::vector<uint8_t>& b) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

std::vector<uint8_t> file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// 8-byte little-endian length, header text, data.
std::vector<uint8_t> st_bytes(const std::string& header, const std::vector<uint8_t>& data, uint64_t len_override = ~0ull) {
  const uint64_t n = len_override == ~0ull ? header.size() : len_override;
  std::vector<uint8_t> out;
  for (int i = 0; i < 8; ++i) out.push_back(uint8_t(n >> (8 * i)));
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

using dvs::test::expect_error;

std::vector<std::pair<std::string, fs::path>> pack_components(const fs::path& folder) {
  return {{"text_encoder", folder / "text_encoder"}, {"transformer", folder / "transformer"}, {"vae", folder / "vae"}};
}

}  // namespace

TEST(Safetensors, ReadsEveryDtypeMetadataAndEdgeShapes) {
  TempDir dir;
  // Data section: a F32 [2,2] at 0, BF16 [3] at 16, a 0-d I32 at 22, U8 [0] (empty), I64 [1] at 26, F16 [2] at
  // 34, BOOL [2] at 38, F8_E4M3 [1] at 40 (gap-free except for the empty tensor).
  const json h = {
      {"__metadata__", {{"format", "pt"}, {"note", "ü"}}},
      {"a", {{"dtype", "F32"}, {"shape", {2, 2}}, {"data_offsets", {0, 16}}}},
      {"b", {{"dtype", "BF16"}, {"shape", {3}}, {"data_offsets", {16, 22}}}},
      {"c", {{"dtype", "I32"}, {"shape", json::array()}, {"data_offsets", {22, 26}}}},
      {"d", {{"dtype", "U8"}, {"shape", {0, 5}}, {"data_offsets", {26, 26}}}},
      {"e", {{"dtype", "I64"}, {"shape", {1}}, {"data_offsets", {26, 34}}}},
      {"f", {{"dtype", "F16"}, {"shape", {2}}, {"data_offsets", {34, 38}}}},
      {"g", {{"dtype", "BOOL"}, {"shape", {2}}, {"data_offsets", {38, 40}}}},
      {"h", {{"dtype", "F8_E4M3"}, {"shape", {1}}, {"data_offsets", {40, 41}}}},
  };
  std::vector<uint8_t> data(41);
  const float a[] = {1, 2, 3, 4};
  std::memcpy(data.data(), a, 16);
  const uint16_t b[] = {0x3f80, 0xc000, 0x7f80};
  std::memcpy(data.data() + 16, b, 6);
  const int32_t c = -42;
  std::memcpy(data.data() + 22, &c, 4);
  put_bytes(dir / "ok.safetensors", st_bytes(h.dump(), data));

  const auto f = dvs::SafetensorsFile::open(dir / "ok.safetensors");
  ASSERT_EQ(f.tensors().size(), 8u);
  EXPECT_EQ(f.tensors()[0].name, "a");  // sorted by name
  EXPECT_EQ(f.metadata().at("format"), "pt");
  EXPECT_EQ(f.metadata().at("note"), "ü");
  EXPECT_EQ(f.data_size(), 41u);
  EXPECT_EQ(f.find("zzz"), nullptr);

  const auto ta = f.load("a");
  EXPECT_EQ(ta.dtype, DType::f32);
  EXPECT_EQ(ta.shape, (dvs::Shape{2, 2}));
  EXPECT_EQ(ta.to_f32(), (std::vector<float>{1, 2, 3, 4}));
  EXPECT_EQ(f.load("b").to_f32(), (std::vector<float>{1.0f, -2.0f, INFINITY}));
  const auto tc = f.load("c");
  EXPECT_TRUE(tc.shape.empty());
  EXPECT_EQ(tc.as<int32_t>()[0], -42);
  EXPECT_EQ(f.load("d").bytes(), 0u);
  EXPECT_EQ(f.find("f")->dtype, DType::f16);

  const auto* e = f.find("e");
  ASSERT_NE(e, nullptr);
  EXPECT_FALSE(e->dtype.has_value());  // I64: listed, not loadable as is
  EXPECT_EQ(e->dtype_name, "I64");
  EXPECT_EQ(e->elem_size, 8u);
  EXPECT_EQ(f.bytes(*e).size(), 8u);
  expect_error([&] { f.load("e"); }, "ok.safetensors", "I64");
  expect_error([&] { f.load("nope"); }, "ok.safetensors", "nope");
  EXPECT_EQ(f.find("h")->elem_size, 1u);

  // Moving keeps the mapping valid.
  dvs::SafetensorsFile moved = dvs::SafetensorsFile::open(dir / "ok.safetensors");
  dvs::SafetensorsFile other = std::move(moved);
  EXPECT_EQ(other.load("a").to_f32(), ta.to_f32());

  // Trailing padding spaces in the header are legal.
  put_bytes(dir / "padded.safetensors", st_bytes(h.dump() + "        ", data));
  EXPECT_EQ(dvs::SafetensorsFile::open(dir / "padded.safetensors").tensors().size(), 8u);
  // So is an empty file with no tensors.
  put_bytes(dir / "none.safetensors", st_bytes("{}", {}));
  EXPECT_TRUE(dvs::SafetensorsFile::open(dir / "none.safetensors").tensors().empty());
}

TEST(Safetensors, DtypeTables) {
  EXPECT_EQ(dvs::safetensors_dtype_size("BF16"), 2u);
  EXPECT_EQ(dvs::safetensors_dtype_size("F8_E5M2"), 1u);
  EXPECT_EQ(dvs::safetensors_dtype_size("U64"), 8u);
  EXPECT_EQ(dvs::safetensors_dtype_size("F4"), 0u);
  EXPECT_EQ(dvs::safetensors_engine_dtype("U8"), DType::u8);
  EXPECT_FALSE(dvs::safetensors_engine_dtype("I64").has_value());
  for (DType t : {DType::f32, DType::f16, DType::bf16, DType::i32, DType::u8})
    EXPECT_EQ(dvs::safetensors_engine_dtype(dvs::safetensors_dtype_name(t)), t);
}

TEST(SafetensorsPack, EveryComponentMatchesItsSchemaF32AndBf16Sharded) {
  for (const char* folder : {"model", "model_bf16"}) {
    const dvs::ModelFolder m = dvs::ModelFolder::open(golden_path() / folder);
    for (const auto& [name, dir] : pack_components(m.root())) {
      SCOPED_TRACE(std::string(folder) + "/" + name);
      const dvs::Component c = m.load(name);
      ASSERT_TRUE(c.weights.has_value());
      const dvs::Schema s = dvs::schema_for(c.entry.class_name, c.config, c.config_path.string());
      const auto issues = dvs::check_schema(s, *c.weights);
      for (const auto& i : issues) ADD_FAILURE() << i.message();
      // dtype: F32 everywhere in model/; BF16 in model_bf16/ except the VAE (kept F32 as on the Hub).
      const std::string want = std::string(folder) == "model_bf16" && name != "vae" ? "BF16" : "F32";
      for (const auto& [tname, ref] : c.weights->entries()) {
        EXPECT_EQ(ref.info->dtype_name, want) << tname;
        EXPECT_EQ(ref.info->nbytes(), ref.info->numel * ref.info->elem_size) << tname;
      }
      // Every schema tensor except the tied T5 embedding is present.
      size_t required = 0;
      for (const auto& spec : s.tensors) required += !spec.optional;
      EXPECT_EQ(c.weights->size(), required);
    }
  }
}

TEST(SafetensorsPack, Bf16CopiesAreTheF32WeightsRounded) {
  const dvs::ModelFolder f32 = dvs::ModelFolder::open(golden_path() / "model");
  const dvs::ModelFolder b16 = dvs::ModelFolder::open(golden_path() / "model_bf16");
  for (const char* comp : {"text_encoder", "transformer"}) {
    const dvs::WeightSet a = f32.weights(comp), b = b16.weights(comp);
    ASSERT_EQ(a.size(), b.size()) << comp;
    size_t exact = 0, total = 0;
    for (const auto& [name, ref] : a.entries()) {
      const auto x = a.load(name).to_f32();
      const auto yt = b.load(name);
      ASSERT_EQ(yt.dtype, DType::bf16) << name;
      const auto y = yt.to_f32();
      ASSERT_EQ(x.size(), y.size()) << name;
      for (size_t i = 0; i < x.size(); ++i) {
        // Within half a bf16 step (2^-9 relative), and mostly exactly our own RNE rounding. The pos_embedding
        // buffer was rounded from float64 directly, so it may differ from f64->f32->bf16 in rare ties.
        EXPECT_LE(std::fabs(y[i] - x[i]), std::ldexp(std::fabs(x[i]), -8)) << name << "[" << i << "]";
        exact += dvs::bf16_to_f32(dvs::f32_to_bf16(x[i])) == y[i];
        ++total;
      }
    }
    EXPECT_GE(double(exact), 0.999 * double(total)) << comp;
  }
}

TEST(SafetensorsPack, LoadsATensorFromEachShard) {
  const dvs::WeightSet w = dvs::WeightSet::open_dir(golden_path() / "model_bf16" / "transformer");
  EXPECT_TRUE(w.sharded());
  EXPECT_EQ(w.files().size(), 3u);
  EXPECT_TRUE(w.warnings().empty());
  std::set<const dvs::WeightFile*> seen;
  for (const auto& [name, ref] : w.entries()) seen.insert(ref.file);
  EXPECT_EQ(seen.size(), 3u);
  const auto pos = w.load("patch_embed.pos_embedding");
  EXPECT_EQ(pos.shape, (dvs::Shape{1, 56, 32}));
  EXPECT_EQ(w.total_bytes(), 119328u);  // = the index's metadata.total_size
}

// ---- corrupt files ----------------------------------------------------------------------------------------------

TEST(SafetensorsCorrupt, EachIsRejectedWithTheFileAndTheProblem) {
  TempDir dir;
  const auto t = [](const std::string& dtype, json shape, json offs) {
    return json{{"dtype", dtype}, {"shape", shape}, {"data_offsets", offs}};
  };
  const std::vector<uint8_t> d16(16), d120(120);
  const std::string ok = json{{"x.weight", t("F32", {2, 2}, {0, 16})}}.dump();
  struct Case {
    std::string file, word;
    std::vector<uint8_t> bytes;
  };
  std::string nested(100000, '[');
  std::vector<Case> cases = {
      {"empty.safetensors", "truncated", {}},
      {"short.safetensors", "truncated", {1, 2, 3, 4, 5}},
      {"hlen_past_eof.safetensors", "past the end of the file", st_bytes(ok, d16, 5000)},
      {"hlen_zero.safetensors", "header length is 0", st_bytes("", d16)},
      {"hlen_huge.safetensors", "exceeds", st_bytes(ok, d16, 1ull << 62)},
      {"hlen_max.safetensors", "exceeds", st_bytes(ok, d16, ~0ull - 1)},
      {"not_json.safetensors", "not valid JSON", st_bytes("{\"x.weight\": {\"dtype\": F32}}", d16)},
      {"not_utf8.safetensors", "UTF-8", st_bytes("{\"x\xff\": {}}", d16)},
      {"overlong_utf8.safetensors", "UTF-8", st_bytes("{\"\xc0\xaf\": {}}", d16)},
      {"nested.safetensors", "nests deeper", st_bytes(nested, d16)},
      {"nested_obj.safetensors", "nests deeper",
       st_bytes([] { std::string s; for (int i = 0; i < 70; ++i) s += "{\"a\":"; return s + "1" + std::string(70, '}'); }(), d16)},
      {"not_object.safetensors", "not an object", st_bytes("[1,2,3]", d16)},
      {"entry_not_object.safetensors", "not an object", st_bytes("{\"x.weight\": 5}", d16)},
      {"overlap.safetensors", "overlap",
       st_bytes(json{{"a.weight", t("F32", {2, 2}, {0, 16})}, {"b.weight", t("F32", {2}, {8, 16})}}.dump(), d16)},
      {"span_size.safetensors", "needs 120",
       st_bytes(json{{"x.weight", t("F32", {5, 6}, {0, 100})}}.dump(), d120)},
      {"unknown_dtype.safetensors", "unknown dtype 'F4'", st_bytes(json{{"x.weight", t("F4", {2}, {0, 1})}}.dump(), d16)},
      {"missing_dtype.safetensors", "dtype",
       st_bytes(json{{"x.weight", {{"shape", {4}}, {"data_offsets", {0, 16}}}}}.dump(), d16)},
      {"negative_shape.safetensors", "negative", st_bytes(json{{"x.weight", t("F32", {-2, -2}, {0, 16})}}.dump(), d16)},
      {"float_shape.safetensors", "non-integer", st_bytes(json{{"x.weight", t("F32", {2.0, 2}, {0, 16})}}.dump(), d16)},
      {"string_shape.safetensors", "non-integer", st_bytes(json{{"x.weight", t("F32", {"2", 2}, {0, 16})}}.dump(), d16)},
      {"shape_not_array.safetensors", "shape", st_bytes(json{{"x.weight", t("F32", 4, {0, 16})}}.dump(), d16)},
      {"overflow_shape.safetensors", "overflows",
       st_bytes(json{{"x.weight", t("F32", {4294967296ull, 4294967296ull, 2}, {0, 16})}}.dump(), d16)},
      {"overflow_bytes.safetensors", "overflows",
       st_bytes(json{{"x.weight", t("F32", {4611686018427387904ull, 2}, {0, 16})}}.dump(), d16)},
      {"past_end.safetensors", "past the end of the data section",
       st_bytes(json{{"x.weight", t("F32", {2, 2}, {8, 24})}}.dump(), d16)},
      {"begin_after_end.safetensors", "begin is after end",
       st_bytes(json{{"x.weight", t("F32", {0}, {16, 0})}}.dump(), d16)},
      {"offsets_arity.safetensors", "data_offsets", st_bytes(json{{"x.weight", t("F32", {4}, {0, 8, 16})}}.dump(), d16)},
      {"offsets_negative.safetensors", "data_offsets", st_bytes(json{{"x.weight", t("F32", {4}, {-1, 15})}}.dump(), d16)},
      {"duplicate.safetensors", "twice",
       st_bytes("{\"x.weight\": {\"dtype\": \"F32\", \"shape\": [4], \"data_offsets\": [0, 16]},"
                " \"x.weight\": {\"dtype\": \"F32\", \"shape\": [4], \"data_offsets\": [0, 16]}}",
                d16)},
      {"duplicate_field.safetensors", "twice",
       st_bytes("{\"x.weight\": {\"dtype\": \"F32\", \"dtype\": \"F16\", \"shape\": [4], \"data_offsets\": [0, 16]}}", d16)},
      {"metadata_type.safetensors", "__metadata__", st_bytes("{\"__metadata__\": {\"format\": 1}}", d16)},
      {"metadata_array.safetensors", "__metadata__", st_bytes("{\"__metadata__\": [1]}", d16)},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.file);
    put_bytes(dir / c.file, c.bytes);
    expect_error([&] { dvs::SafetensorsFile::open(dir / c.file); }, c.file, c.word);
  }
  // The message of the span-size case reads as documented.
  try {
    dvs::SafetensorsFile::open(dir / "span_size.safetensors");
  } catch (const dvs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("tensor 'x.weight': data_offsets [0,100] span 100 bytes but shape [5,6] × F32 needs 120"),
              std::string::npos)
        << e.what();
  }
  expect_error([&] { dvs::SafetensorsFile::open(dir / "absent.safetensors"); }, "absent.safetensors", "No such file");
  expect_error([&] { dvs::SafetensorsFile::open(dir.path); }, dir.path.filename().string(), "not a regular file");
}

TEST(SafetensorsCorrupt, TruncatedPackFileIsRejected) {
  TempDir dir;
  auto bytes = file_bytes(golden_path() / "model" / "transformer" / "diffusion_pytorch_model.safetensors");
  ASSERT_GT(bytes.size(), 1000u);
  bytes.resize(bytes.size() - 100);
  put_bytes(dir / "cut.safetensors", bytes);
  expect_error([&] { dvs::SafetensorsFile::open(dir / "cut.safetensors"); }, "cut.safetensors", "truncated");
}

TEST(SafetensorsCorrupt, NoPrefixOrByteFlipCrashes) {
  // Every prefix of a small valid file, and every header byte replaced by a few hostile values, either opens
  // or throws dvs::Error. Nothing else (no crash, no other exception type).
  TempDir dir;
  const json h = {{"__metadata__", {{"format", "pt"}}},
                  {"a", {{"dtype", "F32"}, {"shape", {2, 2}}, {"data_offsets", {0, 16}}}},
                  {"b", {{"dtype", "BF16"}, {"shape", {3}}, {"data_offsets", {16, 22}}}}};
  const auto good = st_bytes(h.dump(), std::vector<uint8_t>(22, 0x3f));
  const fs::path p = dir / "fuzz.safetensors";
  size_t opened = 0, rejected = 0;
  auto attempt = [&](const std::vector<uint8_t>& b) {
    put_bytes(p, b);
    try {
      const auto f = dvs::SafetensorsFile::open(p);
      for (const auto& t : f.tensors())
        if (t.dtype) (void)f.load(t);
      ++opened;
    } catch (const dvs::Error&) {
      ++rejected;
    }
  };
  for (size_t n = 0; n < good.size(); ++n) attempt(std::vector<uint8_t>(good.begin(), good.begin() + long(n)));
  for (size_t i = 0; i < 8 + h.dump().size(); ++i)
    for (uint8_t v : {uint8_t(0x00), uint8_t('['), uint8_t('"'), uint8_t('9'), uint8_t(0xff), uint8_t(0x80)}) {
      auto b = good;
      b[i] = v;
      attempt(b);
    }
  EXPECT_GT(rejected, 0u);
  EXPECT_GT(opened, 0u);
}
