// The golden comparison every golden test goes through, with the precision rule for 16-bit operands
// (docs/testing.md, "One precision rule for 16-bit operands"):
//   * a result made with fp32 kernel families is judged by the case's tolerance, element by element
//     (|ours − golden| ≤ atol + rtol·|golden|), as always;
//   * a result made with a 16-bit-operand family (tensor cores: fp16 operands, fp32 accumulation) for an op the
//     case exercises passes when it meets that tolerance, or when its error against the fp32 golden is at most
//     2× the error of PyTorch's bf16 run of the same case on both measures (max |diff| and relative L2), the bf16
//     run being stored in the pack beside the golden (<pack>/torch_bf16/<same path>). A pack without that file
//     says so on the result's line and falls back to the element-wise tolerance.
// Every comparison prints dvs's error and the bf16 run's, whichever rule judges it, so a GPU run's log can be
// judged by the same rule.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "io/host_tensor.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"

namespace dvs::test {

// The ops whose kernel family decides how a result is judged (a set: combine with |).
enum GoldenOps : unsigned {
  kNoKernelOps = 0,  // no linear, attention or convolution: elementwise ops, schedulers, K-RNR
  kLinearOps = 1,
  kAttentionOps = 2,
  kConvOps = 4,
  kTextOps = kLinearOps | kAttentionOps,  // T5, the CogVideoX transformer
  kAllKernelOps = kLinearOps | kAttentionOps | kConvOps,  // chains through the VAE and the transformer, VDA
};

// dvs's error against the fp32 golden, in the two measures the rule and the pack README use.
struct ErrorMeasure {
  double max_abs = 0;  // max |ours − golden| (infinity when any value is NaN)
  double rel_l2 = 0;   // ‖ours − golden‖₂ / ‖golden‖₂ (‖golden‖₂ = 0: divided by 1)
};
ErrorMeasure error_measure(const std::vector<float>& ours, const std::vector<float>& golden);

// The 16-bit-operand ops of `ops`, from what ran (tests/support/gpu.hpp's kernels_run_in_test): those that
// dispatched a tensor-core kernel, or a coopmat kernel's fp32 twin (which rounds operands to fp16 as the tensor
// cores do), in the running test. Returns a text naming them ("" when none: the fp32 tolerance judges). A call that fell back to an fp32 kernel (T5's fp32 operands,
// a head_dim the tensor-core kernel does not take) is judged by the fp32 tolerance, as its kernel was fp32.
std::string sixteen_bit_ops_run(const std::vector<vk::Context::KernelNote>& ran, unsigned ops);

// One golden comparison's verdict and the line that reports it.
struct GoldenVerdict {
  bool pass = false;
  std::string report;
};

// The rule itself, on values (shapes checked by the caller). `bf16`: PyTorch's bf16 run of the same golden, or
// nullopt when the pack has none (`bf16_source` then says where it was looked for). `sixteen_bit`: the text of
// sixteen_bit_ops_run ("" for fp32 families).
GoldenVerdict judge_golden(const std::string& what, const std::vector<float>& ours, const std::vector<float>& golden,
                           const std::optional<std::vector<float>>& bf16, const std::string& bf16_source, double atol,
                           double rtol, const std::string& sixteen_bit);

// A golden file of a pack and PyTorch's bf16 run beside it (<root>/torch_bf16/<rel>, when the pack has it).
struct PackGolden {
  HostTensor golden;
  std::optional<HostTensor> bf16;
  std::filesystem::path bf16_path;
};
PackGolden read_pack_golden(const std::filesystem::path& root, const std::string& rel);

// The production comparison: `ours` against <root>/<rel> (a leading batch of one ignored on either side), judged
// by the rule for the ops `ops` by the kernels that ran in this test (or `sixteen_bit` when given: tests of the rule).
// Prints the verdict line, adds a non-fatal failure when it fails; returns the verdict.
GoldenVerdict expect_golden_file(const std::string& what, const Shape& ours_shape, const std::vector<float>& ours,
                                 const std::filesystem::path& root, const std::string& rel, double atol, double rtol,
                                 unsigned ops, const std::optional<std::string>& sixteen_bit = std::nullopt);

// The same with golden and bf16 values the caller derived from the pack's files (a slice, clamped frames) by the
// same transformation; `bf16` nullopt when the pack has no bf16 file.
GoldenVerdict expect_golden_values(const std::string& what, const Shape& ours_shape, const std::vector<float>& ours,
                                   const Shape& golden_shape, const std::vector<float>& golden,
                                   const std::optional<std::vector<float>>& bf16, const std::string& bf16_source,
                                   double atol, double rtol, unsigned ops,
                                   const std::optional<std::string>& sixteen_bit = std::nullopt);

// Pack A (DVS_GOLDEN_DIR) shorthand: `ours` against <pack>/<rel>.
GoldenVerdict expect_golden(const std::string& what, const HostTensor& ours, const std::string& rel, double atol,
                            double rtol, unsigned ops);

}  // namespace dvs::test
