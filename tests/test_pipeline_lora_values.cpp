// `dvs run --lora` checked by value, as a user runs it on the pack's tiny model: the run with the adapter must
// differ from the run without it, and equal the run with the model that `dvs-weights merge-lora` merged from the
// same adapter. Compared: what `dvs run` writes — the DDIM inversion result it stores in the cache (float32
// .npy, the transformer's effect on the inversion) and output.mp4 (the transformer's effect on the sampling,
// through the decode and the 8-bit encoder).
//
// Every run renders with --points (the hard z-buffer splat, deterministic; the soft splat's float atomics may
// sum in any order), so the runs differ only by the model.
// Tolerances. Merged vs unmerged differ by float32 summation order only (W·x + s·B·(A·x) vs (W + s·B·A)·x,
// ~1e-7 relative per GEMM; tests/test_weights_merge_lora.cpp bounds one transformer call at 1e-5 + 1e-4·|ref|):
// ε_inv after the inversion steps within 1e-4 + 1e-3·|ref| (measured 7e-7). output.mp4 is 8-bit H.264, which
// amplifies float differences of that size: today two identical `dvs run --points` commands write one of two
// output.mp4 files that differ by mean |diff| 0.032 (≈4 levels of [−1, 1]), max 0.51 (issue 12, item 11). So
// the videos "equal" at mean |diff| ≤ 0.06 (no per-pixel bound), and the adapter, strong enough to move the
// video by mean ≥ 0.12 (twice that bound), must.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "io/safetensors_writer.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/lora_adapter.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

// A rank-4 adapter (diffusers layout) on the attention projections of both blocks of the pack's transformer
// (inner dim 2 heads × 16), large enough to move the output visibly.
fs::path write_adapter(const fs::path& dir) {
  return test::write_lora_adapter(dir, {"transformer_blocks.0.attn1.to_q", "transformer_blocks.0.attn1.to_v",
                                        "transformer_blocks.1.attn1.to_k", "transformer_blocks.1.attn1.to_out.0"},
                                  11, 1.0f);
}

std::set<fs::path> cache_files(const fs::path& cache) {
  std::set<fs::path> s;
  if (fs::is_directory(cache))
    for (const auto& e : fs::recursive_directory_iterator(cache))
      if (e.is_regular_file() && e.path().filename().string().rfind("eps_inv-", 0) == 0 && e.path().extension() == ".npy")
        s.insert(e.path());  // not the latents, not the entries' commit markers
  return s;
}

struct RunResult {
  HostTensor eps_inv;  // the inversion this run stored in the cache
  HostTensor frames;   // output.mp4 decoded, [F, 3, H, W] in [−1, 1]
};

// One `dvs run` (`command`, writing into in.dir/name); the cache file it added holds its ε_inv.
RunResult run(const test::PipelineInputs& in, const std::string& name, const std::string& command) {
  const auto before = cache_files(in.cache);
  const auto r = test::run_command(command);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  std::vector<fs::path> added;
  for (const auto& f : cache_files(in.cache))
    if (!before.count(f)) added.push_back(f);
  RunResult out;
  EXPECT_EQ(added.size(), 1u) << name << ": each run's model is another cache key, so it must store one inversion";
  if (added.size() == 1) out.eps_inv = read_npy(added[0]);
  if (r.exit_code == 0) out.frames = read_video(in.dir / name / "output.mp4");
  return out;
}

struct Difference {
  double max_abs = 0, mean_abs = 0, worst_excess = 0;  // worst_excess: max of |a − b| − (atol + rtol·|b|)
};

Difference difference(const HostTensor& a, const HostTensor& b, double atol = 0, double rtol = 0) {
  EXPECT_EQ(a.shape, b.shape);
  Difference d;
  if (a.shape != b.shape || a.numel() == 0) {
    d.max_abs = d.mean_abs = d.worst_excess = INFINITY;
    return d;
  }
  const std::vector<float> x = a.to_f32(), y = b.to_f32();
  d.worst_excess = -INFINITY;
  for (size_t i = 0; i < x.size(); ++i) {
    const double e = std::fabs(double(x[i]) - double(y[i]));
    d.max_abs = std::max(d.max_abs, std::isnan(e) ? INFINITY : e);
    d.mean_abs += e;
    d.worst_excess = std::max(d.worst_excess, e - (atol + rtol * std::fabs(double(y[i]))));
  }
  d.mean_abs /= double(x.size());
  return d;
}

TEST(PipelineLora, RunWithLoraEqualsTheMergedModelAndDiffersFromNone) {
  test::PipelineInputs in;
  const std::string adapter = write_adapter(in.dir.path).string() + ":2";
  const fs::path merged = in.dir / "merged_model";
  const auto m = test::run_command(test::program("dvs-weights") + " merge-lora --model '" + in.model.string() + "' --lora '" +
                                   adapter + "' --out '" + merged.string() + "'");
  ASSERT_EQ(m.exit_code, 0) << m.output;

  const RunResult base = run(in, "base", in.command(in.dir / "base", "--points"));
  const RunResult lora = run(in, "lora", in.command(in.dir / "lora", "--points --lora " + adapter));
  std::string merged_cmd = in.command(in.dir / "merged", "--points");  // the same, with --model the merged folder
  merged_cmd.replace(merged_cmd.find(in.model.string()), in.model.string().size(), merged.string());
  const RunResult with_merged = run(in, "merged", merged_cmd);

  const double eps_atol = 1e-4, eps_rtol = 1e-3;
  const Difference eps_same = difference(lora.eps_inv, with_merged.eps_inv, eps_atol, eps_rtol);
  const Difference eps_effect = difference(lora.eps_inv, base.eps_inv);
  const Difference frames_same = difference(lora.frames, with_merged.frames);
  const Difference frames_effect = difference(lora.frames, base.frames);
  std::printf("  eps_inv: --lora vs merged max |diff| %.3e; --lora vs none max |diff| %.3e\n", eps_same.max_abs,
              eps_effect.max_abs);
  std::printf("  output.mp4 ([-1,1]): --lora vs merged mean %.3e max %.3e; --lora vs none mean %.3e max %.3e\n",
              frames_same.mean_abs, frames_same.max_abs, frames_effect.mean_abs, frames_effect.max_abs);

  EXPECT_LE(eps_same.worst_excess, 0) << "ε_inv of --lora and of the merged model differ beyond " << eps_atol << " + "
                                      << eps_rtol << "·|ref|: max |diff| " << eps_same.max_abs;
  EXPECT_GT(eps_effect.max_abs, 100 * eps_atol) << "the adapter must change the inversion";
  const double same_video = 0.06;  // mean |diff| in [−1, 1], see the top of the file
  EXPECT_LE(frames_same.mean_abs, same_video) << "output.mp4 of --lora vs the merged model";
  EXPECT_GT(frames_effect.mean_abs, 2 * same_video) << "the adapter must change output.mp4";
}

}  // namespace
}  // namespace dvs
