#include "support/precision_rule.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <sstream>

#include "io/npy.hpp"
#include "support/files.hpp"
#include "support/golden_compare.hpp"
#include "support/gpu.hpp"

namespace dvs::test {

namespace {

constexpr double kRuleFactor = 2.0;  // dvs may be this many times as far from the fp32 golden as PyTorch's bf16 run

std::string sci(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3e", v);
  return b;
}

}  // namespace

ErrorMeasure error_measure(const std::vector<float>& ours, const std::vector<float>& golden) {
  ErrorMeasure m;
  double diff2 = 0, gold2 = 0;
  for (size_t i = 0; i < ours.size() && i < golden.size(); ++i) {
    const double d = double(ours[i]) - double(golden[i]);
    m.max_abs = std::max(m.max_abs, std::isnan(d) ? INFINITY : std::fabs(d));
    diff2 += d * d;
    gold2 += double(golden[i]) * double(golden[i]);
  }
  m.rel_l2 = std::sqrt(diff2) / (gold2 > 0 ? std::sqrt(gold2) : 1.0);
  if (std::isnan(m.rel_l2)) m.rel_l2 = INFINITY;
  return m;
}

std::string sixteen_bit_ops_run(const std::vector<vk::Context::KernelNote>& ran, unsigned which) {
  std::string s;
  for (const auto& [bit, op] : {std::pair{kLinearOps, "linear"}, {kAttentionOps, "attention"}, {kConvOps, "conv"}}) {
    if (!(which & bit)) continue;
    std::string shaders;  // the 16-bit kernels this op ran: the coopmat family, or a coopmat kernel's twin
    for (const auto& n : ran)
      if (n.op == op && (n.family == "coopmat" || n.shader.find("coopmat") != std::string::npos) &&
          shaders.find(n.shader) == std::string::npos)
        shaders += (shaders.empty() ? "" : " ") + n.shader;
    if (!shaders.empty()) s += (s.empty() ? "" : ", ") + std::string(op) + "=" + shaders;
  }
  return s;
}

GoldenVerdict judge_golden(const std::string& what, const std::vector<float>& ours, const std::vector<float>& golden,
                           const std::optional<std::vector<float>>& bf16, const std::string& bf16_source, double atol,
                           double rtol, const std::string& sixteen_bit) {
  const ErrorMeasure mine = error_measure(ours, golden);
  size_t bad = 0, first_bad = 0;
  for (size_t i = 0; i < ours.size(); ++i) {
    const double d = std::fabs(double(ours[i]) - double(golden[i]));
    if (!(d <= atol + rtol * std::fabs(double(golden[i])))) {
      if (bad++ == 0) first_bad = i;
    }
  }
  const bool in_tolerance = bad == 0;
  std::ostringstream o;
  char name[64];
  std::snprintf(name, sizeof name, "%-44s", what.c_str());
  o << "  " << name << " max |diff| " << sci(mine.max_abs) << ", rel L2 " << sci(mine.rel_l2);
  std::optional<ErrorMeasure> ref;
  if (bf16) {
    ref = error_measure(*bf16, golden);
    o << " | torch bf16: max |diff| " << sci(ref->max_abs) << ", rel L2 " << sci(ref->rel_l2);
  } else {
    o << " | torch bf16: none in the pack (" << bf16_source << ")";
  }
  const std::string fp32_rule = "fp32 rule (atol " + sci(atol) + ", rtol " + sci(rtol) + ")";
  const std::string outside = in_tolerance ? "" : ", " + std::to_string(bad) + " of " + std::to_string(ours.size()) +
                                                      " values outside, first at flat index " +
                                                      std::to_string(first_bad) + " (ours " +
                                                      std::to_string(ours[first_bad]) + ", golden " +
                                                      std::to_string(golden[first_bad]) + ")";
  GoldenVerdict v;
  if (sixteen_bit.empty()) {
    v.pass = in_tolerance;
    o << " | " << fp32_rule << ": " << (v.pass ? "pass" : "FAIL" + outside);
  } else if (ref) {
    const bool within = mine.max_abs <= kRuleFactor * ref->max_abs && mine.rel_l2 <= kRuleFactor * ref->rel_l2;
    v.pass = in_tolerance || within;
    char ratios[96];
    std::snprintf(ratios, sizeof ratios, "%.3g x and %.3g x the bf16 run's", mine.max_abs / ref->max_abs,
                  mine.rel_l2 / ref->rel_l2);
    o << " | 16-bit rule [" << sixteen_bit << "]: " << ratios << " (at most 2 x each"
      << (in_tolerance ? "; within the fp32 tolerance" : "") << "): " << (v.pass ? "pass" : "FAIL");
  } else {
    v.pass = in_tolerance;
    o << " | 16-bit rule [" << sixteen_bit << "] WITHOUT a bf16 reference: falling back to the " << fp32_rule << ": "
      << (v.pass ? "pass" : "FAIL" + outside);
  }
  v.report = o.str();
  return v;
}

PackGolden read_pack_golden(const std::filesystem::path& root, const std::string& rel) {
  PackGolden p{read_npy(root / rel), std::nullopt, root / "torch_bf16" / rel};
  if (std::filesystem::exists(p.bf16_path)) p.bf16 = read_npy(p.bf16_path);
  return p;
}

GoldenVerdict expect_golden_values(const std::string& what, const Shape& ours_shape, const std::vector<float>& ours,
                                   const Shape& golden_shape, const std::vector<float>& golden,
                                   const std::optional<std::vector<float>>& bf16, const std::string& bf16_source,
                                   double atol, double rtol, unsigned ops,
                                   const std::optional<std::string>& sixteen_bit) {
  const auto shapes = same_shape(ours_shape, golden_shape);
  if (!shapes || ours.size() != golden.size() || (bf16 && bf16->size() != golden.size())) {
    ADD_FAILURE() << what << ": " << shapes.message() << " (" << ours.size() << " values, the golden "
                  << golden.size() << ", its bf16 run " << (bf16 ? bf16->size() : 0) << ")";
    return {};
  }
  const std::string mode = sixteen_bit ? *sixteen_bit : sixteen_bit_ops_run(kernels_run_in_test(), ops);
  GoldenVerdict v = judge_golden(what, ours, golden, bf16, bf16_source, atol, rtol, mode);
  std::printf("%s\n", v.report.c_str());
  EXPECT_TRUE(v.pass) << v.report;
  return v;
}

GoldenVerdict expect_golden_file(const std::string& what, const Shape& ours_shape, const std::vector<float>& ours,
                                 const std::filesystem::path& root, const std::string& rel, double atol, double rtol,
                                 unsigned ops, const std::optional<std::string>& sixteen_bit) {
  const PackGolden p = read_pack_golden(root, rel);
  std::optional<std::vector<float>> bf16;
  if (p.bf16) bf16 = p.bf16->to_f32();
  return expect_golden_values(what, ours_shape, ours, p.golden.shape, p.golden.to_f32(), bf16, p.bf16_path.string(),
                              atol, rtol, ops, sixteen_bit);
}

GoldenVerdict expect_golden(const std::string& what, const HostTensor& ours, const std::string& rel, double atol,
                            double rtol, unsigned ops) {
  return expect_golden_file(what, ours.shape, ours.to_f32(), golden_path(), rel, atol, rtol, ops);
}

}  // namespace dvs::test
