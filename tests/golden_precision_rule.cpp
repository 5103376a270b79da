// The precision rule for 16-bit operands (support/precision_rule.hpp, docs/testing.md) tested by itself, through
// the production comparison the golden tests call, on pack A's and pack vda-A's goldens and PyTorch's bf16 runs
// beside them (tests/golden_tools/make_torch_bf16_cogvideox.py, make_torch_bf16_vda.py; vda-A's stored as float16
// where that is exact): a result perturbed to 2.5x the bf16 run's error fails, 1.5x passes, both measures count,
// the fp32 families keep the element-wise tolerance, a pack without bf16 files says so and falls back to it, the
// tuning decides which rule applies, and the errors each pack records are the ones this code measures on the
// files as it reads them.
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/pack.hpp"
#include "support/precision_rule.hpp"
#include "support/vda_pack.hpp"

namespace dvs::test {
namespace {

namespace fs = std::filesystem;

// Goldens of each model family (T5, transformer, VAE decode, the end-to-end chain of pack A; Video-Depth-Anything's
// window forward, whose bf16 run is stored as float16, and its whole clip, stored as float32), with the case
// tolerance.
struct Sample {
  fs::path (*root)();
  const char* rel;
  double atol, rtol;
};
const Sample kSamples[] = {{golden_path, "t5/nomask_last_hidden_state.npy", 1e-5, 1e-4},
                           {golden_path, "transformer/output_t999.npy", 1e-5, 1e-4},
                           {golden_path, "vae/decode_frames.npy", 5e-4, 1e-4},
                           {golden_path, "e2e/final_latent.npy", 1e-4, 1e-4},
                           {vda_golden_path, "window/depth.npy", 1e-4, 2e-5},
                           {vda_golden_path, "e2e/depth.npy", 1e-4, 2e-5}};
const std::string kForced = "linear=coopmat (forced by the test)";

// golden + s · (bf16 run − golden): both of its error measures are exactly s times the bf16 run's.
std::vector<float> scaled_error(const PackGolden& p, double s) {
  const std::vector<float> g = p.golden.to_f32(), b = p.bf16->to_f32();
  std::vector<float> v(g.size());
  for (size_t i = 0; i < g.size(); ++i) v[i] = float(double(g[i]) + s * (double(b[i]) - double(g[i])));
  return v;
}

PackGolden with_bf16(const Sample& s) {
  PackGolden p = read_pack_golden(s.root(), s.rel);
  if (!p.bf16) ADD_FAILURE() << "no " << p.bf16_path << " (tests/golden_tools/make_torch_bf16_*.py write them)";
  return p;
}

GoldenVerdict judge_file_in(const fs::path& root, const Sample& s, const std::vector<float>& ours,
                            const std::string& mode) {
  const PackGolden p = read_pack_golden(root, s.rel);
  return expect_golden_file(s.rel, p.golden.shape, ours, root, s.rel, s.atol, s.rtol, kAllKernelOps, mode);
}

GoldenVerdict judge_file(const Sample& s, const std::vector<float>& ours, const std::string& mode) {
  return judge_file_in(s.root(), s, ours, mode);
}

TEST(PrecisionRule, ErrorMeasureByHand) {
  const ErrorMeasure m = error_measure({1, 2, 3, 4}, {1, 2, 3, 2});
  EXPECT_DOUBLE_EQ(m.max_abs, 2.0);
  EXPECT_DOUBLE_EQ(m.rel_l2, 2.0 / std::sqrt(1.0 + 4 + 9 + 4));
  const ErrorMeasure z = error_measure({0.5f, 0}, {0, 0});  // a zero golden: the denominator is 1
  EXPECT_DOUBLE_EQ(z.rel_l2, 0.5);
  const ErrorMeasure n = error_measure({NAN, 1}, {1, 1});
  EXPECT_TRUE(std::isinf(n.max_abs) && std::isinf(n.rel_l2));
  // NaN never passes, whichever rule judges it.
  EXPECT_FALSE(judge_golden("nan", {NAN}, {1}, std::vector<float>{1.5f}, "", 1, 1, "linear=coopmat").pass);
  EXPECT_FALSE(judge_golden("nan", {NAN}, {1}, std::nullopt, "none", 1, 1, "").pass);
}

TEST(PrecisionRule, TwoAndAHalfTimesTheBf16ErrorFailsOneAndAHalfPasses) {
  for (const Sample& s : kSamples) {
    SCOPED_TRACE(s.rel);
    const PackGolden p = with_bf16(s);
    if (!p.bf16) continue;
    const GoldenVerdict pass = judge_file(s, scaled_error(p, 1.5), kForced);
    EXPECT_TRUE(pass.pass) << pass.report;
    EXPECT_NE(pass.report.find("1.5 x and 1.5 x the bf16 run's"), std::string::npos) << pass.report;
    GoldenVerdict fail;
    EXPECT_NONFATAL_FAILURE(fail = judge_file(s, scaled_error(p, 2.5), kForced), "16-bit rule");
    EXPECT_FALSE(fail.pass) << fail.report;
    // Just under the bar still passes: "at most 2x".
    EXPECT_TRUE(judge_golden(s.rel, scaled_error(p, 1.999), p.golden.to_f32(), p.bf16->to_f32(), "", s.atol, s.rtol,
                             kForced).pass);
  }
}

// Each measure counts on its own: within 2x on one and beyond on the other fails.
TEST(PrecisionRule, BothMeasuresMustBeWithinTwice) {
  const PackGolden p = with_bf16(kSamples[1]);
  ASSERT_TRUE(p.bf16);
  const std::vector<float> g = p.golden.to_f32(), b = p.bf16->to_f32();
  const ErrorMeasure ref = error_measure(b, g);
  // 1.5x everywhere, then one element pushed to 2.5x the bf16 run's max |diff|: max beyond, L2 within.
  std::vector<float> one_spike = scaled_error(p, 1.5);
  one_spike[0] = float(double(g[0]) + 2.5 * ref.max_abs);
  // Every element off by 1.5x the bf16 run's max |diff|: max within, L2 beyond.
  std::vector<float> everywhere(g.size());
  for (size_t i = 0; i < g.size(); ++i) everywhere[i] = float(double(g[i]) + 1.5 * ref.max_abs);
  const ErrorMeasure spike = error_measure(one_spike, g), flat = error_measure(everywhere, g);
  ASSERT_GT(spike.max_abs, 2 * ref.max_abs);
  ASSERT_LE(spike.rel_l2, 2 * ref.rel_l2);
  ASSERT_LE(flat.max_abs, 2 * ref.max_abs);
  ASSERT_GT(flat.rel_l2, 2 * ref.rel_l2);
  EXPECT_FALSE(judge_golden("max beyond", one_spike, g, b, "", 1e-5, 1e-4, kForced).pass);
  EXPECT_FALSE(judge_golden("L2 beyond", everywhere, g, b, "", 1e-5, 1e-4, kForced).pass);
}

// fp32 families keep the case's element-wise tolerance: 1.5x the bf16 error fails there, the golden itself passes,
// and the line still prints the bf16 run's error.
TEST(PrecisionRule, Fp32FamiliesKeepTheCaseTolerance) {
  for (const Sample& s : kSamples) {
    SCOPED_TRACE(s.rel);
    const PackGolden p = with_bf16(s);
    if (!p.bf16) continue;
    GoldenVerdict v;
    EXPECT_NONFATAL_FAILURE(v = judge_file(s, scaled_error(p, 1.5), ""), "fp32 rule");
    EXPECT_NE(v.report.find("torch bf16: max |diff|"), std::string::npos) << v.report;
    EXPECT_TRUE(judge_file(s, p.golden.to_f32(), "").pass);
  }
}

// A pack without torch_bf16/ says so on the line and judges 16-bit results by the fp32 tolerance: the 1.5x result
// that passes with the bf16 file fails without it.
TEST(PrecisionRule, PackWithoutBf16FilesSaysSoAndFallsBack) {
  const Sample s = kSamples[1];
  const PackGolden p = with_bf16(s);
  ASSERT_TRUE(p.bf16);
  TempDir bare;
  fs::create_directories((bare.path / s.rel).parent_path());
  fs::copy_file(s.root() / s.rel, bare.path / s.rel);
  GoldenVerdict v;
  EXPECT_NONFATAL_FAILURE(v = judge_file_in(bare.path, s, scaled_error(p, 1.5), kForced), "WITHOUT a bf16 reference");
  EXPECT_FALSE(v.pass);
  EXPECT_NE(v.report.find("torch bf16: none in the pack (" + (bare.path / "torch_bf16" / s.rel).string() + ")"),
            std::string::npos)
      << v.report;
  EXPECT_NE(v.report.find("falling back to the fp32 rule"), std::string::npos) << v.report;
  EXPECT_TRUE(judge_file_in(bare.path, s, p.golden.to_f32(), kForced).pass);
}

// Which rule applies comes from the kernels that ran: an op is 16-bit when it dispatched the coopmat family or a
// coopmat kernel's fp32 twin (fp16-rounded operands); a call that fell back to an fp32 kernel is not; the ops a case
// exercises select the fields.
TEST(PrecisionRule, TheKernelsThatRanDecideWhichOpsAreSixteenBit) {
  using Note = vk::Context::KernelNote;
  const std::vector<Note> ran = {{"linear", "coopmat", "linear_coopmat", "", false},
                                 {"linear", "tiled", "linear_tiled", "T5's fp32 operands", false},
                                 {"attention", "texel", "attention", "head_dim 24", false},
                                 {"conv", "tiled", "conv_coopmat_twin", "", false}};
  EXPECT_EQ(sixteen_bit_ops_run(ran, kLinearOps), "linear=linear_coopmat");
  EXPECT_EQ(sixteen_bit_ops_run(ran, kNoKernelOps), "");
  EXPECT_EQ(sixteen_bit_ops_run(ran, kAttentionOps), "");
  EXPECT_EQ(sixteen_bit_ops_run(ran, kAllKernelOps), "linear=linear_coopmat, conv=conv_coopmat_twin");
  EXPECT_EQ(sixteen_bit_ops_run({ran[1], ran[2]}, kAllKernelOps), "");
}

// End to end on this device: the production helper judges by the kernels the running test dispatched (the census),
// not by what the tuning asks for. Census notes stand for dispatches here: no kernel ran, so the fp32 rule judges;
// the attention twin's note makes attention results 16-bit; a linear that fell back to an fp32 kernel does not.
TEST(PrecisionRule, ExpectGoldenJudgesByTheKernelsThatRan) {
  const Sample s = kSamples[1];
  const PackGolden p = with_bf16(s);
  ASSERT_TRUE(p.bf16);
  const HostTensor ours = HostTensor::from_f32(p.golden.shape, scaled_error(p, 1.5));
  EXPECT_NONFATAL_FAILURE(expect_golden("nothing ran", ours, s.rel, s.atol, s.rtol, kAttentionOps), "fp32 rule");
  gpu().note_kernel({"linear", "tiled", "linear_tiled", "T5's fp32 operands", false});
  EXPECT_NONFATAL_FAILURE(expect_golden("linear fell back to fp32", ours, s.rel, s.atol, s.rtol, kTextOps),
                          "fp32 rule");
  gpu().note_kernel({"attention", "tiled", "attention_flash_coopmat_twin", "", false});
  EXPECT_EQ(sixteen_bit_ops_run(kernels_run_in_test(), kTextOps), "attention=attention_flash_coopmat_twin");
  EXPECT_TRUE(expect_golden("attention via the twin", ours, s.rel, s.atol, s.rtol, kAttentionOps).pass);
  EXPECT_NONFATAL_FAILURE(expect_golden("convolutions only", ours, s.rel, s.atol, s.rtol, kConvOps), "fp32 rule");
}

// The errors a pack's cases.json records for each bf16 file are the ones this code measures on the file as it reads
// it (the same measure in the generator and the tests; for vda-A's float16 files, the same values), every listed
// file exists, and the goldens named in `required` have one.
void expect_recorded_measures(const fs::path& root, const nlohmann::json& index, size_t min_files,
                              std::initializer_list<const char*> required) {
  if (!index.contains("torch_bf16"))
    GTEST_SKIP() << root << "/cases.json has no torch_bf16 section: 16-bit families fall back to the fp32 "
                            "tolerances (tests/golden_tools/make_torch_bf16_*.py add it)";
  const auto& files = index.at("torch_bf16").at("files");
  EXPECT_GT(files.size(), min_files);
  for (const auto& [rel, rec] : files.items()) {
    SCOPED_TRACE(rel);
    const PackGolden p = read_pack_golden(root, rel);
    ASSERT_TRUE(p.bf16) << p.bf16_path;
    ASSERT_EQ(p.bf16->shape, p.golden.shape);
    if (rec.contains("stored_as"))  // the storage the record claims is the one read
      EXPECT_EQ(p.bf16->dtype, rec.at("stored_as") == "float32" ? DType::f32 : DType::f16) << rec.dump();
    const ErrorMeasure m = error_measure(p.bf16->to_f32(), p.golden.to_f32());
    const double max_abs = rec.at("max_abs"), rel_l2 = rec.at("rel_l2");  // finite: the scale of the check
    EXPECT_NEAR(m.max_abs, max_abs, 1e-6 * max_abs);
    EXPECT_NEAR(m.rel_l2, rel_l2, 1e-6 * rel_l2);
    EXPECT_GT(m.max_abs, 0.0) << "a bf16 run equal to the golden would demand an exact result";
  }
  for (const char* rel : required) EXPECT_TRUE(files.contains(rel)) << rel;
}

TEST(PrecisionRule, PackRecordsTheMeasureTheTestsUse) {
  expect_recorded_measures(golden_path(), pack_cases(), 60,
                           {"t5/masked_last_hidden_state.npy", "transformer/output_t500.npy", "vae/encode_moments.npy",
                            "vae/tiled_decode_frames.npy", "vae/even2_decode_frames.npy", "e2e/final_frames.npy",
                            "bf16_sharded/transformer_output_t999.npy"});
}

TEST(PrecisionRule, VdaPackRecordsTheMeasureTheTestsUse) {
  expect_recorded_measures(vda_golden_path(), vda_cases(), 90,
                           {"encoder/tap0.npy", "temporal/m0_attn0_context.npy", "temporal/m3_out.npy",
                            "head/output_interp_frame0.npy", "window/depth.npy", "e2e/window_depth_upsampled.npy",
                            "e2e/align_scale_shift.npy", "e2e/depth.npy", "e2e/depth_metric_mode.npy"});
  if (HasFatalFailure() || IsSkipped()) return;
  // The window forward's files are bf16 values stored exactly as float16: that path is read too.
  EXPECT_EQ(read_pack_golden(vda_golden_path(), "window/depth.npy").bf16->dtype, DType::f16);
}

}  // namespace
}  // namespace dvs::test
