// PyTorch .pth reader on crafted archives: pickles written byte by byte, zips written with libzip. Valid
// files (any record prefix, strided / offset views, several dtypes, the {"state_dict": ...} wrapper and the
// "module." prefix) must read back exactly; every kind of corruption must be a dvs::Error naming the file
// and the problem.
#include <gtest/gtest.h>
#include <zip.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "dvs/error.hpp"
#include "io/pickle_state_dict.hpp"
#include "io/pth_file.hpp"
#include "support/files.hpp"

namespace fs = std::filesystem;
using dvs::test::TempDir;

namespace {

// Emits protocol-2 pickle opcodes as torch.save writes them.
struct Pickle {
  std::string b;
  Pickle& op(char c) { b.push_back(c); return *this; }
  Pickle& raw(const std::string& s) { b += s; return *this; }
  Pickle& u32(uint32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(char((v >> (8 * i)) & 0xff));
    return *this;
  }
  Pickle& proto() { return op('\x80').op('\x02'); }
  Pickle& str(const std::string& s) { return op('X').u32(uint32_t(s.size())).raw(s); }
  Pickle& integer(int64_t v) {
    if (v >= 0 && v < 256) return op('K').op(char(v));
    if (v >= 0 && v < 65536) return op('M').op(char(v & 0xff)).op(char(v >> 8));
    if (v >= INT32_MIN && v <= INT32_MAX) return op('J').u32(uint32_t(int32_t(v)));
    op('\x8a').op('\x08');
    for (int i = 0; i < 8; ++i) b.push_back(char((uint64_t(v) >> (8 * i)) & 0xff));
    return *this;
  }
  Pickle& global(const std::string& module, const std::string& name) { return op('c').raw(module + "\n" + name + "\n"); }
  Pickle& mark() { return op('('); }
  Pickle& tuple() { return op('t'); }
  Pickle& ints(const std::vector<int64_t>& v) {
    mark();
    for (int64_t x : v) integer(x);
    return tuple();
  }
  Pickle& ordered_dict() { return global("collections", "OrderedDict").op(')').op('R'); }
  // One `name: tensor` pair as torch.save writes it (key, then _rebuild_tensor_v2(...)).
  Pickle& tensor(const std::string& name, const std::string& storage_class, const std::string& key, int64_t storage_numel,
                 int64_t offset, const std::vector<int64_t>& shape, const std::vector<int64_t>& stride) {
    str(name).global("torch._utils", "_rebuild_tensor_v2").mark();
    mark().str("storage").global("torch", storage_class).str(key).str("cpu").integer(storage_numel).tuple().op('Q');
    integer(offset).ints(shape).ints(stride).op('\x89').ordered_dict().tuple().op('R');
    return *this;
  }
  Pickle& stop() { return op('.'); }
};

template <class T>
std::string bytes_of(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

// Writes a zip archive of stored (uncompressed) records, as torch.save does.
void write_zip(const fs::path& path, const std::vector<std::pair<std::string, std::string>>& records) {
  int err = 0;
  zip_t* za = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  ASSERT_NE(za, nullptr);
  for (const auto& [name, data] : records) {
    zip_source_t* src = zip_source_buffer(za, data.data(), data.size(), 0);
    ASSERT_NE(src, nullptr);
    const zip_int64_t idx = zip_file_add(za, name.c_str(), src, ZIP_FL_ENC_UTF_8);
    ASSERT_GE(idx, 0) << zip_strerror(za);
    zip_set_file_compression(za, zip_uint64_t(idx), ZIP_CM_STORE, 0);
  }
  ASSERT_EQ(zip_close(za), 0);
}

// The good archive every corruption case starts from: a 2x3 f32 tensor, its transpose and a slice sharing one
// storage, an f16 and a bf16 tensor, and an i64 scalar.
struct Crafted {
  std::string prefix = "archive/";
  std::vector<float> f32{0, 1, 2, 3, 4, 5};
  std::vector<uint16_t> f16{0x3c00, 0xc000};  // 1, -2
  std::vector<uint16_t> bf16{0x3f80, 0x4040};  // 1, 3
  std::vector<int64_t> i64{7};

  Pickle state_dict() const {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
    p.tensor("w_t", "FloatStorage", "0", 6, 0, {3, 2}, {1, 3});
    p.tensor("tail", "FloatStorage", "0", 6, 4, {2}, {1});
    p.tensor("h", "HalfStorage", "1", 2, 0, {2}, {1});
    p.tensor("b", "BFloat16Storage", "2", 2, 0, {1, 2}, {2, 1});
    p.tensor("step", "LongStorage", "3", 1, 0, {}, {});
    p.op('u');
    return p;
  }
  std::vector<std::pair<std::string, std::string>> records(const std::string& pickle) const {
    return {{prefix + "data.pkl", pickle},
            {prefix + "byteorder", "little"},
            {prefix + "data/0", bytes_of(f32)},
            {prefix + "data/1", bytes_of(f16)},
            {prefix + "data/2", bytes_of(bf16)},
            {prefix + "data/3", bytes_of(i64)},
            {prefix + "version", "3\n"}};
  }
};

std::vector<float> floats(const std::vector<uint8_t>& b) {
  std::vector<float> v(b.size() / 4);
  std::memcpy(v.data(), b.data(), v.size() * 4);
  return v;
}

using dvs::test::expect_error;

}  // namespace

TEST(PthReader, CraftedArchiveReadsBackExactly) {
  for (const std::string prefix : {"archive/", "some_model_name/"}) {
    TempDir dir;
    Crafted c;
    c.prefix = prefix;
    const fs::path p = dir / "m.pth";
    write_zip(p, c.records(c.state_dict().stop().b));
    const dvs::PthFile f = dvs::PthFile::open(p);
    EXPECT_EQ(f.record_prefix(), prefix);
    ASSERT_EQ(f.tensors().size(), 6u);
    const std::vector<std::string> order{"w", "w_t", "tail", "h", "b", "step"};
    for (size_t i = 0; i < order.size(); ++i) EXPECT_EQ(f.tensors()[i].name, order[i]) << "state_dict order";

    const auto* w = f.find("w");
    ASSERT_TRUE(w);
    EXPECT_EQ(w->dtype_name, "F32");
    EXPECT_EQ(w->shape, (dvs::Shape{2, 3}));
    EXPECT_TRUE(w->contiguous);
    EXPECT_EQ(floats(f.read_bytes(*w)), (std::vector<float>{0, 1, 2, 3, 4, 5}));
    const auto* wt = f.find("w_t");
    EXPECT_FALSE(wt->contiguous);
    EXPECT_EQ(floats(f.read_bytes(*wt)), (std::vector<float>{0, 3, 1, 4, 2, 5})) << "transpose gathered row-major";
    EXPECT_EQ(floats(f.read_bytes(*f.find("tail"))), (std::vector<float>{4, 5})) << "storage offset applied";

    const dvs::HostTensor h = f.load("h");
    EXPECT_EQ(h.dtype, dvs::DType::f16);
    EXPECT_EQ(h.to_f32(), (std::vector<float>{1, -2}));
    const dvs::HostTensor b = f.load("b");
    EXPECT_EQ(b.dtype, dvs::DType::bf16);
    EXPECT_EQ(b.shape, (dvs::Shape{1, 2}));
    EXPECT_EQ(b.to_f32(), (std::vector<float>{1, 3}));

    const auto* step = f.find("step");
    EXPECT_EQ(step->dtype_name, "I64");
    EXPECT_EQ(step->shape, dvs::Shape{});
    EXPECT_EQ(step->numel, 1u);
    const auto sb = f.read_bytes(*step);
    ASSERT_EQ(sb.size(), 8u);
    int64_t v = 0;
    std::memcpy(&v, sb.data(), 8);
    EXPECT_EQ(v, 7);
    expect_error([&] { f.load(*step); }, p.string(), "I64");
    EXPECT_EQ(f.total_bytes(), 6 * 4 + 6 * 4 + 2 * 4 + 2 * 2 + 2 * 2 + 8u);
  }
}

TEST(PthReader, WrapperAndModulePrefixAreUnwrapped) {
  TempDir dir;
  Crafted c;
  Pickle p;
  // {"epoch": 3, "state_dict": {"module.w": ..., "module.h": ...}} as training scripts save it.
  p.proto().op('}').mark().str("epoch").integer(3).str("state_dict").op('}').mark();
  p.tensor("module.w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
  p.tensor("module.h", "HalfStorage", "1", 2, 0, {2}, {1});
  p.op('u').op('u').stop();
  write_zip(dir / "m.pth", c.records(p.b));
  const dvs::PthFile f = dvs::PthFile::open(dir / "m.pth");
  EXPECT_EQ(f.unwrapped(), "state_dict");
  EXPECT_TRUE(f.stripped_module_prefix());
  ASSERT_EQ(f.tensors().size(), 2u);
  EXPECT_EQ(f.tensors()[0].name, "w");
  EXPECT_EQ(f.tensors()[1].name, "h");
  EXPECT_EQ(floats(f.read_bytes(*f.find("w"))), (std::vector<float>{0, 1, 2, 3, 4, 5}));

  // A partial "module." prefix is a real name and stays.
  Pickle q;
  q.proto().ordered_dict().mark();
  q.tensor("module.w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
  q.tensor("h", "HalfStorage", "1", 2, 0, {2}, {1});
  q.op('u').stop();
  write_zip(dir / "n.pth", c.records(q.b));
  const dvs::PthFile g = dvs::PthFile::open(dir / "n.pth");
  EXPECT_FALSE(g.stripped_module_prefix());
  EXPECT_TRUE(g.find("module.w"));
}

TEST(PthReader, NotAZipTruncatedOrWithoutPickle) {
  TempDir dir;
  Crafted c;
  const fs::path good = dir / "good.pth";
  write_zip(good, c.records(c.state_dict().stop().b));
  const std::string all = dvs::test::read_text(good);

  const fs::path text = dir / "text.pth";
  dvs::test::write_text(text, "this is not a zip archive at all, just some words");
  expect_error([&] { dvs::PthFile::open(text); }, text.string(), "not a readable PyTorch checkpoint");
  const fs::path empty = dir / "empty.pth";
  dvs::test::write_text(empty, "");
  expect_error([&] { dvs::PthFile::open(empty); }, empty.string(), "zip");
  const fs::path cut = dir / "cut.pth";
  dvs::test::write_text(cut, all.substr(0, all.size() / 2));
  expect_error([&] { dvs::PthFile::open(cut); }, cut.string(), "zip");
  expect_error([&] { dvs::PthFile::open(dir / "absent.pth"); }, (dir / "absent.pth").string(), "cannot read");

  auto recs = c.records(c.state_dict().stop().b);
  recs.erase(recs.begin());  // no data.pkl
  write_zip(dir / "nopkl.pth", recs);
  expect_error([&] { dvs::PthFile::open(dir / "nopkl.pth"); }, (dir / "nopkl.pth").string(), "no data.pkl");

  auto two = c.records(c.state_dict().stop().b);
  two.emplace_back("other/data.pkl", two[0].second);
  write_zip(dir / "two.pth", two);
  expect_error([&] { dvs::PthFile::open(dir / "two.pth"); }, (dir / "two.pth").string(), "2 data.pkl records");

  auto big = c.records(c.state_dict().stop().b);
  big[1].second = "big";
  write_zip(dir / "big.pth", big);
  expect_error([&] { dvs::PthFile::open(dir / "big.pth"); }, (dir / "big.pth").string(), "little-endian");
}

// Each corrupt pickle is rejected with the problem named and, for the parser's own errors, the byte offset.
TEST(PthReader, BadPicklesAreRejected) {
  TempDir dir;
  Crafted c;
  struct Case {
    std::string name, pickle, word;
  };
  const std::string good = c.state_dict().stop().b;
  std::vector<Case> cases;
  cases.push_back({"truncated", good.substr(0, good.size() / 2), "truncated pickle"});
  cases.push_back({"no_stop", good.substr(0, good.size() - 1), "truncated pickle"});
  cases.push_back({"unknown_opcode", Pickle().proto().op('\x93').stop().b, "unsupported pickle opcode 0x93"});
  cases.push_back({"float_opcode", Pickle().proto().op('G').raw(std::string(8, '\0')).stop().b, "opcode 0x47 ('G')"});
  cases.push_back({"os_system", Pickle().proto().global("os", "system").str("ls").op('\x85').op('R').stop().b,
                   "global 'os.system' is not allowed"});
  cases.push_back({"builtins_eval", Pickle().proto().global("builtins", "eval").stop().b, "builtins.eval"});
  cases.push_back({"unknown_storage", Pickle().proto().global("torch", "ComplexFloatStorage").stop().b,
                   "torch.ComplexFloatStorage"});
  cases.push_back({"underflow_tuple2", Pickle().proto().op('\x86').stop().b, "stack underflow"});
  cases.push_back({"underflow_setitem", Pickle().proto().op('}').str("k").op('s').stop().b, "stack underflow"});
  cases.push_back({"setitems_no_mark", Pickle().proto().op('}').op('u').stop().b, "no MARK"});
  cases.push_back({"memo_missing", Pickle().proto().op('h').op('\x05').stop().b, "memo key 5"});
  cases.push_back({"two_values_at_stop", Pickle().proto().op('}').op('}').stop().b, "2 values on the stack"});
  cases.push_back({"not_a_dict", Pickle().proto().integer(5).stop().b, "not a state_dict"});
  cases.push_back({"too_many_objects", Pickle().proto().raw(std::string(size_t(1) << 20, ')')).stop().b,
                   "more than 524288 objects"});
  cases.push_back({"long1_too_long", Pickle().proto().op('\x8a').op('\x09').raw(std::string(9, '\1')).stop().b,
                   "does not fit in 64 bits"});
  {
    Pickle p;
    p.proto().ordered_dict().mark().str("x").integer(3).op('u').stop();
    cases.push_back({"non_tensor_value", p.b, "'x' is a int, not a tensor"});
  }
  {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
    p.tensor("w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
    p.op('u').stop();
    cases.push_back({"duplicate_key", p.b, "duplicate key 'w'"});
  }
  {
    Pickle p;  // a wrapper dict with its "state_dict" key twice
    p.proto().op('}').mark();
    p.str("state_dict").op('}').mark();
    p.tensor("module.w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
    p.op('u').str("state_dict").integer(1).op('u').stop();
    cases.push_back({"duplicate_wrapper_key", p.b, "duplicate key 'state_dict'"});
  }
  {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "0", 6, 0, {2, 3}, {3});
    p.op('u').stop();
    cases.push_back({"rank_mismatch", p.b, "size has 2 dimensions but its stride has 1"});
  }
  {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "0", 6, 0, {2, -3}, {3, 1});
    p.op('u').stop();
    cases.push_back({"negative_size", p.b, "negative entry -3"});
  }
  {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "0", 6, -1, {2, 3}, {3, 1});
    p.op('u').stop();
    cases.push_back({"negative_offset", p.b, "negative storage offset"});
  }
  {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "../../etc/passwd", 6, 0, {2, 3}, {3, 1});
    p.op('u').stop();
    cases.push_back({"key_with_path", p.b, "not a plain record name"});
  }
  for (const auto& k : cases) {
    SCOPED_TRACE(k.name);
    const fs::path p = dir / (k.name + ".pth");
    write_zip(p, c.records(k.pickle));
    expect_error([&] { dvs::PthFile::open(p); }, p.string(), k.word);
  }
}

TEST(PthReader, ParserErrorsGiveTheByteOffset) {
  // PROTO 2 (2 bytes), EMPTY_DICT at 2, then an unknown opcode at byte 3.
  const std::string b = Pickle().proto().op('}').op('\xff').stop().b;
  try {
    dvs::parse_state_dict_pickle({reinterpret_cast<const uint8_t*>(b.data()), b.size()}, "f.pth");
    ADD_FAILURE() << "no error";
  } catch (const dvs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("f.pth: data.pkl byte 3: unsupported pickle opcode 0xff"), std::string::npos)
        << e.what();
  }
  const std::string g = Pickle().proto().global("posix", "system").stop().b;
  try {
    dvs::parse_state_dict_pickle({reinterpret_cast<const uint8_t*>(g.data()), g.size()}, "g.pth");
    ADD_FAILURE() << "no error";
  } catch (const dvs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("g.pth: data.pkl byte 2: global 'posix.system'"), std::string::npos) << e.what();
  }
}

// Storages: missing, wrong size, tensors out of their bounds, overflowing or overlapping views.
TEST(PthReader, StorageProblemsAreRejected) {
  TempDir dir;
  Crafted c;
  auto one = [](const std::string& storage, int64_t numel, int64_t offset, std::vector<int64_t> shape,
                std::vector<int64_t> stride, const std::string& key = "0") {
    Pickle p;
    p.proto().ordered_dict().mark().tensor("w", storage, key, numel, offset, shape, stride).op('u').stop();
    return p.b;
  };
  struct Case {
    std::string name, pickle, word;
  };
  const int64_t big = int64_t(1) << 62;
  std::vector<Case> cases{
      {"missing_storage", one("FloatStorage", 6, 0, {2, 3}, {3, 1}, "9"), "storage record archive/data/9 is missing"},
      {"storage_size", one("FloatStorage", 7, 0, {2, 3}, {3, 1}), "holds 24 bytes but the pickle declares 7 elements"},
      {"storage_type_size", one("DoubleStorage", 6, 0, {2, 3}, {3, 1}), "holds 24 bytes but the pickle declares 6"},
      {"out_of_bounds_offset", one("FloatStorage", 6, 1, {2, 3}, {3, 1}), "out of bounds"},
      {"out_of_bounds_shape", one("FloatStorage", 6, 0, {3, 3}, {3, 1}), "out of bounds"},
      {"out_of_bounds_stride", one("FloatStorage", 6, 0, {2, 3}, {4, 1}), "out of bounds"},
      {"huge_shape", one("FloatStorage", 6, 0, {big, big}, {1, 1}), "overflows"},
      {"huge_stride", one("FloatStorage", 6, 0, {8}, {big}), "overflows"},
      {"huge_offset", one("FloatStorage", 6, big, {2}, {1}), "out of bounds"},
      {"huge_storage_numel", one("FloatStorage", big, 0, {2}, {1}), "holds 24 bytes"},
      {"expanded", one("FloatStorage", 6, 0, {4, 3}, {0, 1}), "repeats"},
      {"overlapping", one("FloatStorage", 6, 0, {2, 3}, {1, 1}), "overlap"},
  };
  {
    Pickle p;
    p.proto().ordered_dict().mark();
    p.tensor("w", "FloatStorage", "0", 6, 0, {2, 3}, {3, 1});
    p.tensor("v", "IntStorage", "0", 6, 0, {2, 3}, {3, 1});
    p.op('u').stop();
    cases.push_back({"storage_two_types", p.b, "declared both FloatStorage and IntStorage"});
  }
  for (const auto& k : cases) {
    SCOPED_TRACE(k.name);
    const fs::path p = dir / (k.name + ".pth");
    write_zip(p, c.records(k.pickle));
    expect_error([&] { dvs::PthFile::open(p); }, p.string(), k.word);
  }
  // An empty tensor needs no bytes, even at the storage's end.
  const fs::path e = dir / "empty_tensor.pth";
  write_zip(e, c.records(one("FloatStorage", 6, 6, {0, 3}, {3, 1})));
  const dvs::PthFile f = dvs::PthFile::open(e);
  EXPECT_EQ(f.find("w")->numel, 0u);
  EXPECT_TRUE(f.read_bytes(*f.find("w")).empty());
}

// A data record changed after the archive was written is caught by its CRC when read.
TEST(PthReader, CorruptStorageBytesFailOnRead) {
  TempDir dir;
  Crafted c;
  c.f32 = std::vector<float>(64, 1.5f);  // a recognisable run of bytes inside the file
  Pickle p;
  p.proto().ordered_dict().mark().tensor("w", "FloatStorage", "0", 64, 0, {64}, {1}).op('u').stop();
  const fs::path path = dir / "m.pth";
  write_zip(path, c.records(p.b));
  std::string all = dvs::test::read_text(path);
  const std::string needle = bytes_of(std::vector<float>(64, 1.5f));
  const size_t at = all.find(needle);
  ASSERT_NE(at, std::string::npos);
  all[at + 100] ^= 0x10;
  dvs::test::write_text(path, all);
  const dvs::PthFile f = dvs::PthFile::open(path);
  expect_error([&] { f.read_bytes(*f.find("w")); }, path.string(), "archive/data/0 is truncated or corrupt");
}
