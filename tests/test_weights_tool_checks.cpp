// dvs-weights as a user meets it when something is wrong: NaN/Inf weights found by `inspect --values`, a
// pipeline component without its weights, `make-tiny --out` naming a file, and the help of make-tiny.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "io/safetensors.hpp"
#include "support/files.hpp"
#include "support/process.hpp"
#include "support/pth_edit.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
const std::string kTool = test::program("dvs-weights");

// A make-tiny model (one transformer layer, small T5) in `dir`.
void make_tiny(const fs::path& dir, const std::string& dtype) {
  const auto r = test::run_command(kTool + " make-tiny --out " + dir.string() + " --layers 1 --t5-layers 1 --dtype " + dtype);
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

// Overwrites element `index` of tensor `name` in a .safetensors file with `bits` (the element's raw bytes).
void poke(const fs::path& file, const std::string& name, uint64_t index, const void* bits, size_t size) {
  uint64_t offset = 0;
  {
    const SafetensorsFile f = SafetensorsFile::open(file);
    const TensorInfo* t = f.find(name);
    ASSERT_NE(t, nullptr) << name;
    ASSERT_LT(index, t->numel);
    offset = 8 + f.header_size() + t->begin + index * t->elem_size;
  }
  std::fstream io(file, std::ios::in | std::ios::out | std::ios::binary);
  io.seekp(std::streamoff(offset));
  io.write(static_cast<const char*>(bits), std::streamsize(size));
}

const char* kTransformer = "transformer/diffusion_pytorch_model.safetensors";
const char* kWeight = "transformer_blocks.0.attn1.to_q.weight";  // 2-D: the index is printed as [row,column]

TEST(WeightsToolValues, CleanModelPassesAndNaNIsLocated) {
  test::TempDir d;
  make_tiny(d / "m", "f32");
  const auto clean = test::run_command(kTool + " inspect --summary --values " + (d / "m").string());
  EXPECT_EQ(clean.exit_code, 0) << clean.output;
  EXPECT_NE(clean.output.find("values: OK"), std::string::npos) << clean.output;

  const SafetensorsFile f = SafetensorsFile::open(d / "m" / kTransformer);
  const int64_t cols = f.find(kWeight)->shape[1];
  const uint64_t index = uint64_t(2 * cols + 3);  // row 2, column 3
  const float nan = std::numeric_limits<float>::quiet_NaN();
  poke(d / "m" / kTransformer, kWeight, index, &nan, 4);
  // Without --values the file is structurally fine (the schema check passes): the NaN is found only by reading.
  EXPECT_EQ(test::run_command(kTool + " inspect --summary " + (d / "m").string()).exit_code, 0);
  const auto bad = test::run_command(kTool + " inspect --summary --values " + (d / "m").string());
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find(std::string("tensor '") + kWeight + "'"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("holds NaN, first at element " + std::to_string(index) + " [2,3]"), std::string::npos)
      << bad.output;
  // Only the poisoned tensor is named.
  EXPECT_EQ(test::count_of(bad.output, "holds NaN"), 1u) << bad.output;
}

TEST(WeightsToolValues, InfinityInBf16IsFoundInASingleFile) {
  test::TempDir d;
  make_tiny(d / "m", "bf16");
  const uint16_t inf_bf16 = 0xff80;  // −Inf
  // The first element of the tensor: an off-by-one scan start would miss it.
  poke(d / "m" / kTransformer, kWeight, 0, &inf_bf16, 2);
  const auto bad = test::run_command(kTool + " inspect --values " + (d / "m" / kTransformer).string());
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("holds an infinite value, first at element 0 [0,0]"), std::string::npos) << bad.output;
  // The largest finite bf16 (exponent 0xfe): the f16 rule (exponent bits 0x7c00) would call it non-finite.
  make_tiny(d / "n", "bf16");
  const uint16_t finite = 0x7f7f;
  poke(d / "n" / kTransformer, kWeight, 5, &finite, 2);
  EXPECT_EQ(test::run_command(kTool + " inspect --values " + (d / "n" / kTransformer).string()).exit_code, 0);
}

// A .pth is checked as the loaders read it: NaN weights in a valid archive, and a record whose CRC fails (which
// dvs depth refuses), both fail --values naming the tensor; the intact file passes.
TEST(WeightsToolValues, PthNaNAndDamagedRecordsAreFound) {
  test::TempDir d;
  const auto pack = test::vda_checkpoint_path();
  const std::string tensor = "pretrained.blocks.0.attn.qkv.weight";
  fs::copy_file(pack.parent_path() / "config.json", d / "config.json");  // the tiny size is described there
  const auto clean = test::run_command(kTool + " inspect --summary --values " + pack.string());
  EXPECT_EQ(clean.exit_code, 0) << clean.output;
  EXPECT_NE(clean.output.find("values: OK"), std::string::npos) << clean.output;

  test::write_pth_filled(pack, d / "nan.pth", tensor, std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(test::run_command(kTool + " inspect --summary " + (d / "nan.pth").string()).exit_code, 0)
      << "the structure is fine: only reading the values finds the NaN";
  const auto nan = test::run_command(kTool + " inspect --summary --values " + (d / "nan.pth").string());
  EXPECT_EQ(nan.exit_code, 1) << nan.output;
  EXPECT_NE(nan.output.find("tensor '" + tensor + "'"), std::string::npos) << nan.output;
  EXPECT_NE(nan.output.find("holds NaN"), std::string::npos) << nan.output;

  test::write_pth_bad_crc(pack, d / "crc.pth", tensor);
  const auto crc = test::run_command(kTool + " inspect --summary --values " + (d / "crc.pth").string());
  EXPECT_EQ(crc.exit_code, 1) << crc.output;
  EXPECT_NE(crc.output.find("tensor '" + tensor + "'"), std::string::npos) << crc.output;
  EXPECT_NE(crc.output.find("damaged"), std::string::npos) << crc.output;
}

TEST(WeightsToolInspect, ListedComponentWithoutWeightsFails) {
  test::TempDir d;
  make_tiny(d / "m", "f32");
  EXPECT_EQ(test::run_command(kTool + " inspect --summary " + (d / "m").string()).exit_code, 0);
  fs::remove(d / "m" / "vae" / "diffusion_pytorch_model.safetensors");
  const auto r = test::run_command(kTool + " inspect --summary " + (d / "m").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("vae: model_index.json lists it as AutoencoderKLCogVideoX"), std::string::npos) << r.output;
  // The tokenizer and the scheduler have no weights and are not errors.
  EXPECT_EQ(test::count_of(r.output, "dvs-weights: error:"), 1u) << r.output;
}

// The tokenizer has no weights but one file dvs cannot run without: its absence fails inspect, naming the file.
TEST(WeightsToolInspect, TokenizerWithoutItsVocabularyFails) {
  test::TempDir d;
  make_tiny(d / "m", "f32");
  fs::remove(d / "m" / "tokenizer" / "spiece.model");
  const auto r = test::run_command(kTool + " inspect --summary " + (d / "m").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find((d / "m" / "tokenizer" / "spiece.model").string() + " is missing"), std::string::npos) << r.output;
  EXPECT_EQ(test::count_of(r.output, "dvs-weights: error:"), 1u) << r.output;
}

TEST(WeightsToolMakeTiny, OutNamingAFileIsAClearErrorAndHelpStatesLatentUnits) {
  test::TempDir d;
  test::write_text(d / "file.txt", "not a folder");
  const auto r = test::run_command(kTool + " make-tiny --out " + (d / "file.txt").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;  // not 134 (an uncaught exception)
  EXPECT_NE(r.output.find("file.txt is a file; it must name a folder"), std::string::npos) << r.output;
  EXPECT_EQ(test::read_text(d / "file.txt"), "not a folder");

  const auto help = test::run_command(kTool + " make-tiny --help");
  EXPECT_EQ(help.exit_code, 0) << help.output;
  EXPECT_NE(help.output.find("--sample is the transformer's sample size in LATENT units"), std::string::npos) << help.output;
  // Usage errors exit 2, like every other dvs command.
  EXPECT_EQ(test::run_command(kTool + " make-tiny --out " + (d / "x").string() + " --bogus").exit_code, 2);
  EXPECT_EQ(test::run_command(kTool + " make-tiny --out " + (d / "x").string() + " --sample 8x8").exit_code, 2);
  EXPECT_EQ(test::run_command(kTool + " inspect --bogus x").exit_code, 2);
  EXPECT_EQ(test::run_command(kTool + " inspect --help").exit_code, 0);
}

}  // namespace
}  // namespace dvs
