// One face for weight files (io/weight_file.hpp): a checkpoint opens as what its bytes are, whatever its name
// says, through the one loader every model uses (WeightSet), and a file of neither format is refused by name.
// The .pth content is the vda-A pack's real checkpoint; the safetensors content is written here with known values.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "io/pth_file.hpp"
#include "io/safetensors_writer.hpp"
#include "io/weight_file.hpp"
#include "io/weight_set.hpp"
#include "models/vda/vda_model.hpp"
#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "support/vda_pack.hpp"

namespace fs = std::filesystem;
using dvs::test::expect_error;
using dvs::test::TempDir;

namespace {

// Copies `from` to dir/name (and the config.json beside it, which describes the pack's architecture).
fs::path copy_as(const fs::path& from, const TempDir& dir, const std::string& name) {
  fs::copy_file(from, dir / name, fs::copy_options::overwrite_existing);
  if (fs::exists(from.parent_path() / "config.json"))
    fs::copy_file(from.parent_path() / "config.json", dir / "config.json", fs::copy_options::overwrite_existing);
  return dir / name;
}

}  // namespace

TEST(WeightFile, PthContentOpensWhateverItsExtension) {
  const fs::path original = dvs::test::vda_checkpoint_path();
  const dvs::PthFile reference = dvs::PthFile::open(original);
  ASSERT_FALSE(reference.tensors().empty());
  const auto& probe = reference.tensors().front();
  const std::vector<uint8_t> probe_bytes = reference.read_bytes(probe);
  const dvs::VdaConfig want = dvs::VdaModel::inspect(original);

  TempDir dir;
  for (const std::string name : {"ckpt.pth", "ckpt.safetensors", "ckpt.bin", "ckpt"}) {
    SCOPED_TRACE(name);
    const fs::path p = copy_as(original, dir, name);
    EXPECT_EQ(dvs::weight_file_format(p), dvs::WeightFormat::pth);
    const dvs::WeightSet w = dvs::WeightSet::open_file(p);
    ASSERT_EQ(w.files().size(), 1u);
    EXPECT_STREQ(w.files()[0]->format_name(), "PyTorch .pth");
    EXPECT_EQ(w.files()[0]->path(), p);
    ASSERT_EQ(w.size(), reference.tensors().size());
    for (const auto& t : reference.tensors()) {
      const dvs::WeightRef* r = w.find(t.name);
      ASSERT_NE(r, nullptr) << t.name;
      EXPECT_EQ(r->info->shape, t.shape) << t.name;
      EXPECT_EQ(r->info->dtype_name, t.dtype_name) << t.name;
    }
    const dvs::TensorBytes got = w.bytes(probe.name);
    EXPECT_EQ(std::vector<uint8_t>(got.data(), got.data() + got.size()), probe_bytes);
    // The VDA model reads its checkpoint through the same loader: the renamed file is the same model.
    const dvs::VdaConfig c = dvs::VdaModel::inspect(p);
    EXPECT_EQ(c.embed_dim, want.embed_dim);
    EXPECT_EQ(c.depth, want.depth);
    EXPECT_EQ(c.features, want.features);
    EXPECT_EQ(c.out_channels, want.out_channels);
  }
}

TEST(WeightFile, SafetensorsContentOpensWhateverItsExtension) {
  dvs::HostTensor a({2, 3}, dvs::DType::f32);
  for (int i = 0; i < 6; ++i) a.as<float>()[i] = float(i) - 2.5f;
  dvs::HostTensor b({4}, dvs::DType::i32);
  for (int i = 0; i < 4; ++i) b.as<int32_t>()[i] = 7 * i - 3;
  TempDir dir;
  for (const std::string name : {"w.safetensors", "w.pth", "w.bin", "w"}) {
    SCOPED_TRACE(name);
    dvs::write_safetensors(dir / name, {{"a", a}, {"b", b}});
    EXPECT_EQ(dvs::weight_file_format(dir / name), dvs::WeightFormat::safetensors);
    const dvs::WeightSet w = dvs::WeightSet::open_file(dir / name);
    ASSERT_EQ(w.files().size(), 1u);
    EXPECT_STREQ(w.files()[0]->format_name(), "safetensors");
    ASSERT_EQ(w.size(), 2u);
    EXPECT_EQ(w.load("a").shape, (dvs::Shape{2, 3}));
    EXPECT_EQ(w.load("a").data, a.data);
    EXPECT_EQ(w.load("b").data, b.data);
    EXPECT_EQ(w.files()[0]->metadata().at("format"), "pt");
  }
}

TEST(WeightFile, NeitherFormatIsRejectedNamingTheFile) {
  TempDir dir;
  dvs::test::write_text(dir / "notes.pth", "these are notes, not weights");
  dvs::test::write_text(dir / "short.safetensors", "abc");
  dvs::test::write_text(dir / "empty.bin", "");
  // A JSON text is not a safetensors file: its '{' is at byte 0, not after an 8-byte length.
  dvs::test::write_text(dir / "config.safetensors", "{\"_class_name\": \"AutoencoderKLCogVideoX\"}");
  for (const std::string name : {"notes.pth", "short.safetensors", "empty.bin", "config.safetensors"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(dvs::weight_file_format(dir / name), dvs::WeightFormat::neither);
    expect_error([&] { dvs::WeightSet::open_file(dir / name); }, (dir / name).string(), "neither safetensors");
    expect_error([&] { dvs::WeightFile::open(dir / name); }, (dir / name).string(), "PyTorch checkpoint (a zip archive");
  }
  expect_error([&] { dvs::WeightSet::open_file(dir / "absent.pth"); }, (dir / "absent.pth").string(), "no such weight file");
  expect_error([&] { dvs::WeightSet::open_file(dir.path); }, dir.path.string(), "not a regular file");
}

TEST(WeightFile, AnEntryOfAnotherFileIsRefused) {
  dvs::HostTensor a({2}, dvs::DType::f32);
  TempDir dir;
  dvs::write_safetensors(dir / "one.safetensors", {{"a", a}});
  dvs::write_safetensors(dir / "two.safetensors", {{"a", a}});
  const auto one = dvs::WeightFile::open(dir / "one.safetensors");
  const auto two = dvs::WeightFile::open(dir / "two.safetensors");
  const dvs::WeightEntry* from_two = two->find("a");
  ASSERT_NE(from_two, nullptr);
  EXPECT_EQ(one->load(*one->find("a")).data, a.data);
  expect_error([&] { one->load(*from_two); }, "one.safetensors", "is not from this file");
  expect_error([&] { one->bytes(*from_two); }, "one.safetensors", "is not from this file");
}
