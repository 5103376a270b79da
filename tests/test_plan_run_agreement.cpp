// `dvs plan --device`, `dvs run --check` and a real `dvs run` agree about the allocation limit: with
// maxMemoryAllocationSize forced (DVS_LIMITS=alloc=N) over a range from where nothing fits to where everything
// runs untiled, at every value the plan's verdict (untiled / tiled with HxW / nothing fits) is the preflight's,
// and a real run does what they say: it succeeds untiled, or it stops before any stage with the preflight's own
// reason (and, where the plan named a tile, runs with that tile). The range includes each boundary the plan
// draws, a byte either side, so a plan figure below what a call really allocates shows as a run failing late.
// The model is the conformance pack's (64x64, 9 frames: seconds per run on lavapipe).
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>
#include <vector>

#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

using nlohmann::json;

enum class Verdict { untiled, tiled, nothing };

const char* name(Verdict v) { return v == Verdict::untiled ? "untiled" : v == Verdict::tiled ? "tiled" : "nothing fits"; }

struct Outcome {
  Verdict verdict = Verdict::nothing;
  std::string tile;    // "HxW" when tiled
  std::string reason;  // the preflight's problem lines, when it refused
};

std::string limits_env(uint64_t alloc) { return "DVS_LIMITS=alloc=" + std::to_string(alloc) + " "; }

json plan_json(const test::PipelineInputs& in, const std::string& env) {
  const auto r = test::run_command(env + test::program("dvs") + " plan --model " + in.model.string() +
                                   " --frames 9 --height 64 --width 64 --device 0 --json");
  EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 1) << r.output;
  return json::parse(r.output.substr(r.output.find('{')));
}

Outcome plan_verdict(const json& plan) {
  const json& c = plan.at("choice");
  if (!c.at("fits").get<bool>()) return {Verdict::nothing, "", ""};
  if (!c.at("tiled").get<bool>()) return {Verdict::untiled, "", ""};
  return {Verdict::tiled,
          std::to_string(c.at("tile_sample_min_height").get<int>()) + "x" + std::to_string(c.at("tile_sample_min_width").get<int>()), ""};
}

// The problem lines of a preflight refusal ("  - ..."), without the surrounding text.
std::string problems_of(const std::string& output) {
  std::string lines;
  size_t at = output.find("preflight found");
  if (at == std::string::npos) return "";
  for (size_t p = output.find("\n  - ", at); p != std::string::npos; p = output.find("\n  - ", p + 1))
    lines += output.substr(p + 1, output.find('\n', p + 1) - p - 1) + "\n";
  return lines;
}

Outcome check_verdict(const test::CommandResult& r) {
  if (r.exit_code == 0) return {Verdict::untiled, "", ""};
  Outcome o{Verdict::nothing, "", problems_of(r.output)};
  if (const size_t p = o.reason.find("add --vae-tile "); p != std::string::npos) {
    o.verdict = Verdict::tiled;
    const size_t start = p + std::string("add --vae-tile ").size();
    o.tile = o.reason.substr(start, o.reason.find(' ', start) - start);
  }
  return o;
}

TEST(PlanRunAgreement, AllocationLimitSweep) {
  test::PipelineInputs in;
  // The boundaries the plan draws: the largest allocation of the untiled setting and of the smallest tile it
  // offers, read from its own report with the limit out of the way.
  const json open = plan_json(in, limits_env(1ull << 40));
  auto largest = [](const json& tiling) {
    return std::max(tiling.at("vae_encode").at("limits").at("largest_tensor_bytes").get<uint64_t>(),
                    tiling.at("vae_decode").at("limits").at("largest_tensor_bytes").get<uint64_t>());
  };
  ASSERT_GE(open.at("tilings").size(), 2u) << "the pack's size must offer a tile";
  const uint64_t untiled = largest(open.at("tilings").front()), tiled = largest(open.at("tilings").back());
  ASSERT_LT(tiled, untiled);
  std::vector<uint64_t> sweep = {512 << 10, tiled - 1, tiled, (tiled + untiled) / 2, untiled - 1, untiled, untiled * 3 / 2};
  sweep.push_back(4ull << 20);
  std::sort(sweep.begin(), sweep.end());

  std::set<Verdict> seen;
  for (const uint64_t alloc : sweep) {
    SCOPED_TRACE("DVS_LIMITS=alloc=" + std::to_string(alloc));
    const Outcome plan = plan_verdict(plan_json(in, limits_env(alloc)));
    const auto check = test::run_command(limits_env(alloc) + in.command(in.dir / "check", "--no-cache --check"));
    const Outcome checked = check_verdict(check);
    EXPECT_EQ(name(checked.verdict), std::string(name(plan.verdict))) << check.output;
    EXPECT_EQ(checked.tile, plan.tile) << check.output;
    seen.insert(plan.verdict);

    // The real run, as the user would start it after the plan: no tiling.
    const auto out = in.dir / ("out_" + std::to_string(alloc));
    const auto run = test::run_command(limits_env(alloc) + in.command(out, "--no-cache"));
    if (plan.verdict == Verdict::untiled) {
      EXPECT_EQ(run.exit_code, 0) << run.output;
      EXPECT_TRUE(std::filesystem::exists(out / "output.mp4")) << run.output;
      continue;
    }
    EXPECT_NE(run.exit_code, 0) << run.output;
    EXPECT_EQ(run.output.find("\"stage\":"), std::string::npos) << "a stage started\n" << run.output;
    EXPECT_EQ(problems_of(run.output), checked.reason) << "the run stopped for another reason\n" << run.output;
    EXPECT_FALSE(checked.reason.empty()) << check.output;
    if (plan.verdict == Verdict::tiled) {  // the tile the plan names runs
      const auto tiled_out = in.dir / ("tiled_" + std::to_string(alloc));
      const auto with_tile = test::run_command(limits_env(alloc) + in.command(tiled_out, "--no-cache --vae-tile " + plan.tile));
      EXPECT_EQ(with_tile.exit_code, 0) << with_tile.output;
      EXPECT_TRUE(std::filesystem::exists(tiled_out / "output.mp4")) << with_tile.output;
    }
  }
  EXPECT_EQ(seen.size(), 3u) << "the sweep must meet all three verdicts";
}

// The render stage is in the same estimate. The splat renderer splits a clip over frames, never a frame: one
// frame's accumulation (4 words per pixel: 64 x 64 x 16 B = 64 KiB at the pack's size) must fit one storage
// binding, while the models' ops split their tensors over bindings. With maxStorageBufferRange forced below and
// above that, the plan and --check refuse exactly where the run fails (before any stage, with the same reason,
// naming the render and a --size that fits), and where they pass the run renders and finishes.
TEST(PlanRunAgreement, BindingLimitOnlyTheRenderMeets) {
  test::PipelineInputs in;
  const uint64_t frame_accumulation = 64 * 64 * 16;
  for (const uint64_t binding : {frame_accumulation / 2, frame_accumulation - 1024, frame_accumulation}) {
    const std::string env = "DVS_LIMITS=binding=" + std::to_string(binding) + " ";
    SCOPED_TRACE(env);
    const bool fits = binding >= frame_accumulation;
    const json plan = plan_json(in, env);
    EXPECT_EQ(plan.at("choice").at("fits").get<bool>(), fits) << plan.dump(1);
    EXPECT_EQ(plan.at("render").at("runs").get<bool>(), fits) << plan.dump(1);
    const auto check = test::run_command(env + in.command(in.dir / "check", "--no-cache --check"));
    EXPECT_EQ(check.exit_code == 0, fits) << check.output;
    const auto out = in.dir / ("out_" + std::to_string(binding));
    const auto run = test::run_command(env + in.command(out, "--no-cache"));
    if (fits) {
      EXPECT_EQ(run.exit_code, 0) << run.output;
      EXPECT_TRUE(std::filesystem::exists(out / "output.mp4")) << run.output;
      continue;
    }
    const std::string reason = problems_of(check.output);
    EXPECT_NE(reason.find("render: one 64x64 frame needs 64.00 KiB for the splat accumulation"), std::string::npos) << check.output;
    EXPECT_NE(reason.find("use a smaller --size"), std::string::npos) << check.output;
    EXPECT_NE(run.exit_code, 0) << run.output;
    EXPECT_EQ(run.output.find("\"stage\":"), std::string::npos) << "a stage started\n" << run.output;
    EXPECT_EQ(problems_of(run.output), reason) << "the run stopped for another reason\n" << run.output;
  }
}

// run --check names the memory it plans against as `dvs info` does: the budget dvs will use on the device
// ("device memory for dvs: ..."), not another figure (the heap a CPU device reports is not its limit).
TEST(PlanRunAgreement, CheckNamesTheBudgetDvsInfoShows) {
  test::PipelineInputs in;
  const auto info = test::run_command("DVS_LIMITS= " + test::program("dvs") + " info");
  ASSERT_EQ(info.exit_code, 0) << info.output;
  const std::string key = "device memory for dvs: ";
  const size_t i = info.output.find(key);
  ASSERT_NE(i, std::string::npos) << info.output;
  const auto check = test::run_command("DVS_LIMITS= " + in.command(in.dir / "out", "--check --progress bar"));
  ASSERT_EQ(check.exit_code, 0) << check.output;
  const size_t c = check.output.find(key);
  ASSERT_NE(c, std::string::npos) << check.output;
  // The same source, in the same words (the amount itself moves with the host's free memory).
  auto source = [&](const std::string& text, size_t at) {
    const size_t open = text.find('(', at);
    return text.substr(open, text.find('\n', open) - open);
  };
  EXPECT_EQ(source(check.output, c), source(info.output, i)) << check.output;
}

}  // namespace
}  // namespace dvs
