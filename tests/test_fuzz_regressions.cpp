// Inputs the fuzz harnesses (tests/fuzz) found or that guard what they found, fed through the production readers:
// each must end in a dvs::Error that names the file and the problem, never a crash, a hang or an allocation the
// file cannot justify. The inputs live in tests/fuzz/corpus/<harness>/ so the fuzzer starts from them too.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "io/depth.hpp"
#include "io/depth_images.hpp"
#include "geometry/trajectory_json.hpp"
#include "spec/cogvideox_config.hpp"
#include "spec/t5_config.hpp"
#include "dvs/run_record.hpp"
#include "support/files.hpp"
#include "support/expect_error.hpp"
#include "support/source_dir.hpp"

namespace {

std::filesystem::path corpus_file(const std::string& harness, const std::string& name) {
  return dvs::test::source_dir() / "tests" / "fuzz" / "corpus" / harness / name;
}

// Copied under the name a reader dispatches on (the corpus files carry no extension), in a fresh temporary folder.
class FuzzRegressions : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("dvs-fuzz-regressions-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path as(const std::string& harness, const std::string& name, const std::string& file_name) {
    const std::filesystem::path to = dir_ / file_name;
    std::filesystem::copy_file(corpus_file(harness, name), to);
    return to;
  }
  // Depth images go through OpenCV: a build without video I/O (DVS_VIDEO_IO=OFF) refuses them all alike.
  bool without_video_io() {
    const std::string e = dvs::test::error_of([&] { dvs::read_depth_png(as("depth_png", "gray8_3x3", "probe.png")); });
    return e.find("DVS_VIDEO_IO=OFF") != std::string::npos;
  }
  std::filesystem::path dir_;
};

// fuzz_npz: a zip64 member whose header claims 2 GiB in a 266-byte archive; the reader allocated the claim before
// reading. Now the claim is held to what the compressed bytes can expand to.
TEST_F(FuzzRegressions, NpzMemberClaimingMoreThanItsCompressedBytesIsRefused) {
  const auto file = as("npz", "regression_member_size_claim", "depth.npz");
  dvs::test::expect_error([&] { dvs::load_depth(file); }, {file.string(), "claims", "corrupt archive"});
  EXPECT_EQ(dvs::load_depth(as("npz", "depths_compressed", "seed.npz")).shape, (dvs::Shape{2, 4, 4}));
}

// fuzz_run_record: a run.json without "height" (one byte of the key changed) escaped as nlohmann's out_of_range
// instead of an error naming the file and the key.
TEST_F(FuzzRegressions, RunJsonWithoutHeightNamesTheKey) {
  const auto file = corpus_file("run_record", "regression_height_missing");
  dvs::test::expect_error([&] { dvs::run_record_arguments(file); }, {file.string(), "\"height\" is missing"});
  const auto seed = corpus_file("run_record", "full");
  EXPECT_FALSE(dvs::run_record_arguments(seed).empty());
}

// Found with it, by reading: a "lora" entry of the wrong types, and nesting deep enough for dump()'s recursion.
TEST_F(FuzzRegressions, RunJsonWithMalformedLoraOrDeepNestingIsRefused) {
  const std::string record = dvs::test::read_text(corpus_file("run_record", "full"));
  const std::string lora = "\"lora\": {\"file\": \"/loras/style.safetensors\", \"scale\": 0.8}";
  ASSERT_NE(record.find(lora), std::string::npos);
  std::string bad_lora = record;
  bad_lora.replace(bad_lora.find(lora), lora.size(), "\"lora\": {\"file\": 7, \"scale\": \"x\"}");
  dvs::test::write_text(dir_ / "lora.json", bad_lora);
  dvs::test::expect_error([&] { dvs::run_record_arguments(dir_ / "lora.json"); }, {"lora.json", "\"lora\" must hold"});
  dvs::test::write_text(dir_ / "deep.json", std::string(100000, '[') + std::string(100000, ']'));
  dvs::test::expect_error([&] { dvs::run_record_arguments(dir_ / "deep.json"); }, {"deep.json", "nests deeper than 64"});
}

// fuzz_model_folder: a transformer config.json with "timestep_activation_fn": 64 escaped as nlohmann's type_error.
// The input is the fuzzer's multi-file form: the transformer's config is its second part.
TEST_F(FuzzRegressions, ConfigWithNonStringActivationNamesTheKey) {
  const std::string input = dvs::test::read_text(corpus_file("model_folder", "regression_activation_not_a_string"));
  const std::string separator = "\n=====\n";
  const size_t begin = input.find(separator) + separator.size(), end = input.find(separator, begin);
  ASSERT_NE(end, std::string::npos);
  const nlohmann::json config = nlohmann::json::parse(input.substr(begin, end - begin));
  dvs::test::expect_error([&] { dvs::CogVideoXTransformerConfig::from_json(config, "transformer/config.json"); },
                          {"transformer/config.json", "'timestep_activation_fn' must be a string"});
}

// The same class of escape, found by reading the config readers after it: every value's type and size is checked.
TEST_F(FuzzRegressions, ConfigValuesOfTheWrongTypeOrSizeNameTheKey) {
  using nlohmann::json;
  dvs::test::expect_error([&] { dvs::T5EncoderConfig::from_json(json{{"feed_forward_proj", 3}}, "t5.json"); },
                          {"t5.json", "'feed_forward_proj' must be a string"});
  dvs::test::expect_error([&] { dvs::CogVideoXTransformerConfig::from_json(json{{"num_layers", int64_t(1) << 40}}, "t.json"); },
                          {"t.json", "'num_layers' must be an integer in 0..2147483648"});
  dvs::test::expect_error([&] { dvs::VaeConfig::from_json(json{{"block_out_channels", "128"}}); },
                          {"vae config", "'block_out_channels' must be a non-empty list"});
  dvs::test::expect_error([&] { dvs::VaeConfig::from_json(json{{"block_out_channels", std::vector<int>(70, 8)}}); },
                          {"vae config", "'block_out_channels' has 70 levels"});
  dvs::test::expect_error([&] { dvs::VaeConfig::from_json(json{{"scaling_factor", "0.7"}}); },
                          {"vae config", "'scaling_factor' must be a number"});
  dvs::test::expect_error([&] { dvs::VaeConfig::from_json(json{{"use_quant_conv", 1}}); },
                          {"vae config", "'use_quant_conv' must be true or false"});
  EXPECT_EQ(dvs::VaeConfig::from_json(json{{"sample_height", 480.0}}).sample_height, 480);  // integral floats still read
}

// fuzz_trajectory_json: a number past double's range (…E54444444) escaped as nlohmann's out_of_range.
TEST_F(FuzzRegressions, TrajectoryJsonWithAnOverflowingNumberIsAnError) {
  const auto file = corpus_file("trajectory_json", "regression_number_overflow");
  dvs::test::expect_error([&] { dvs::geometry::parse_trajectory_json(dvs::test::read_text(file), "camera.json"); },
                          {"camera.json", "not valid JSON", "number overflow"});
}

// fuzz_depth_png: a 69-byte PNG declaring 30000x30000 16-bit pixels made OpenCV allocate 1.8 GB before failing.
TEST_F(FuzzRegressions, PngDeclaringMorePixelsThanADepthFrameIsRefused) {
  if (without_video_io()) GTEST_SKIP() << "built without video I/O";
  const auto file = as("depth_png", "declared_30000x30000", "d_0001.png");
  dvs::test::expect_error([&] { dvs::read_depth_png(file); }, {file.string(), "declares a 30000x30000 image", "at most"});
}

TEST_F(FuzzRegressions, PngDeclaringMoreThanItsBytesCanHoldIsRefused) {
  if (without_video_io()) GTEST_SKIP() << "built without video I/O";
  const auto file = as("depth_png", "declared_more_than_file_holds", "d_0001.png");
  dvs::test::expect_error([&] { dvs::read_depth_png(file); }, {file.string(), "declares a 4000x4000 image", "bytes can hold"});
}

// fuzz_depth_exr: the same through an EXR header's dataWindow.
TEST_F(FuzzRegressions, ExrDeclaringMorePixelsThanADepthFrameIsRefused) {
  if (without_video_io()) GTEST_SKIP() << "built without video I/O";
  const auto file = as("depth_exr", "declared_30000x30000", "d_0001.exr");
  dvs::test::expect_error([&] { dvs::read_depth_exr(file); }, {file.string(), "declares a 30000x30000 image", "at most"});
}

// fuzz_depth_png and fuzz_depth_exr: OpenCV picks its decoder by content, so this file (EXR magic, a DICOM marker
// at byte 128) reached Debian's GDCM through either name, whose assertion aborted the process. A .png must start
// with the PNG signature and a .exr with the EXR magic; an EXR with the DICOM marker is refused before OpenCV.
TEST_F(FuzzRegressions, DepthImagesOpenCvWouldDecodeAsAnotherFormatAreRefused) {
  if (without_video_io()) GTEST_SKIP() << "built without video I/O";
  const auto png = as("depth_png", "regression_exr_magic_and_dicom_marker", "d_0001.png");
  dvs::test::expect_error([&] { dvs::read_depth_png(png); }, {png.string(), "not a PNG file", "PNG signature"});
  const auto exr = as("depth_exr", "regression_dicom_marker_at_128", "d_0002.exr");
  dvs::test::expect_error([&] { dvs::read_depth_exr(exr); }, {exr.string(), "DICOM marker at byte 128"});
  const auto png_named_exr = as("depth_png", "gray16_4x6", "d_0003.exr");
  dvs::test::expect_error([&] { dvs::read_depth_exr(png_named_exr); }, {png_named_exr.string(), "not an EXR file"});
}

// The seeds themselves are valid files: the checks above refuse only what is declared too large.
TEST_F(FuzzRegressions, SeedDepthImagesStillRead) {
  if (without_video_io()) GTEST_SKIP() << "built without video I/O";
  EXPECT_EQ(dvs::read_depth_png(as("depth_png", "gray16_4x6", "a.png")).shape, (dvs::Shape{4, 6}));
  EXPECT_EQ(dvs::read_depth_exr(as("depth_exr", "float_3x4.exr", "b.exr")).shape, (dvs::Shape{3, 4}));
}

}  // namespace
