// The command line on CLI11 (issue 24 item 7, issue 25's command-line items): every usage error exits 2 with
// one wording that names the option and the command's --help; --help works on every sub-command and goes to
// stdout; `dvs render` takes the options `dvs run --help` says it shares (and they act); contradictory flags
// are refused; batch jobs' keys are read against dvs run's declarations.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
const std::string kDvs = test::program("dvs");

// A 5-frame 48x64 clip and its metric depth.
struct RenderInputs {
  test::TempDir dir;
  fs::path video = dir / "v.mp4", depth = dir / "d.npy";
  RenderInputs() {
    HostTensor rgb({5, 3, 48, 64}, DType::f32);
    for (int64_t i = 0; i < rgb.numel(); ++i) rgb.as<float>()[i] = float((i * 7919) % 200) / 100.0f - 1.0f;
    write_video(video, rgb, 10);
    HostTensor d({5, 48, 64}, DType::f32);
    for (int64_t i = 0; i < d.numel(); ++i) d.as<float>()[i] = 2.0f + float(i % 13) * 0.1f;
    write_npy(depth, d);
  }
  // The command, in a subshell so that `extra` may redirect stdout or stderr (run_command adds 2>&1 outside).
  std::string render(const fs::path& out, const std::string& extra) const {
    return "(" + kDvs + " render --video " + video.string() + " --depth " + depth.string() + " --metric-depth --frames 5 --out " +
           out.string() + " " + extra + ")";
  }
};

TEST(CliCommandLine, EveryUsageErrorExitsTwoWithOneWording) {
  test::TempDir d;
  test::write_text(d / "jobs.jsonl", "{\"prompt\": \"x\"}\n");
  const std::string run = "run --video v.mp4 --depth d.npy --model m --out o --prompt p ";
  struct Case {
    std::string args, command, names;
  };
  // Each of these exited 1 (a failed run) or was accepted before: the command line itself is wrong.
  const std::vector<Case> cases = {
      {run + "--preset fast", "run", "--preset"},
      {run + "--lora x:abc", "run", "--lora"},
      {run + "--vae-tile 50x50", "run", "--vae-tile"},
      {run + "--size 60x60", "run", "--size"},
      {run + "--frames 10", "run", "4k+1"},
      {run + "--progress fancy --quiet", "run", "--progress"},
      {run + "--progress bar --quiet", "run", "--quiet"},
      {"plan --model cogvideox-5b-i2v --frames 10", "plan", "4k+1"},
      {"plan --model cogvideox-5b-i2v --height 240 --width 360", "plan", "multiples of 16"},
      {"plan --model cogvideox-5b-i2v --limits tpu", "plan", "tpu"},
      {"batch " + (d / "jobs.jsonl").string() + " --shard 3/2", "batch", "--shard"},
      {"batch", "batch", "jobs file"},
      {"render --video v.mp4 --depth d.npy --out o --progress json --quiet", "render", "--quiet"},
      {"render --video v.mp4 --depth d.npy --out o --height 60 --width 64", "render", "multiples of 8"},
      {"depth --video v.mp4 --out o.npz --quiet --progress bar", "depth", "--quiet"},
      {"invert --video v.mp4 --depth d.npy --model m --out o --preset fast", "invert", "--preset"},
      {"render --video", "render", "--video needs a value"},
      {"info --bogus", "info", "unknown option --bogus"},
  };
  for (const Case& c : cases) {
    const auto r = test::run_command(kDvs + " " + c.args);
    EXPECT_EQ(r.exit_code, 2) << "dvs " << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find("dvs: error: dvs " + c.command + ": "), std::string::npos) << "dvs " << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find("(see dvs " + c.command + " --help)"), std::string::npos) << "dvs " << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.names), std::string::npos) << "dvs " << c.args << "\n" << r.output;
  }
}

// --help on stdout with status 0, listing every option the command takes.
TEST(CliCommandLine, HelpOnEverySubcommandGoesToStdout) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> commands = {
      {"info", {"--device"}},
      {"render", {"--video", "--depth-model", "--height", "--width", "--quiet", "--progress", "--check", "--no-glb"}},
      {"run", {"--video", "--height", "--lora", "--vae-tile", "--quiet", "--check", "--from"}},
      {"demo", {"--out", "--quiet"}},
      {"invert", {"--inversion-steps", "--vae-tiling", "--cache-dir"}},
      {"encode-prompt", {"--model", "--prompt", "--out"}},
      {"batch", {"--shard", "--prompt", "--seed"}},
      {"plan", {"--budget", "--limits", "--depth-model", "--video-size"}},
      {"depth", {"--input-size", "--max-res", "--quiet"}},
      {"cache", {"--cache-dir", "--older-than", "--max-size", "--all", "--dry-run"}},
  };
  for (const auto& [cmd, options] : commands) {
    // run_command captures stdout and stderr together: the subshells keep one of them.
    const auto r = test::run_command("(" + kDvs + " " + cmd + " --help 2>/dev/null)");
    const auto err = test::run_command("(" + kDvs + " " + cmd + " --help 2>&1 >/dev/null)");
    const std::string& help = r.output;
    EXPECT_EQ(r.exit_code, 0) << "dvs " << cmd << " --help\n" << help;
    EXPECT_EQ(err.output, "") << "dvs " << cmd << " --help wrote to stderr";
    EXPECT_EQ(help.rfind("usage: dvs " + cmd, 0), 0u) << help;
    for (const auto& o : options) EXPECT_NE(help.find(o), std::string::npos) << "dvs " << cmd << " --help lacks " << o << "\n" << help;
  }
  // run's help says its inputs are dvs render's: every input option of run's help is in render's.
  const auto run_help = test::run_command(kDvs + " run --help").output;
  const auto render_help = test::run_command(kDvs + " render --help").output;
  for (const char* o : {"--video", "--depth", "--depth-model", "--depth-input-size", "--metric-depth", "--trim-depth",
                        "--depth-fit", "--trajectory", "--frames", "--size", "--height", "--width", "--resize",
                        "--intrinsics", "--points", "--cache-dir", "--no-cache", "--device", "--progress", "--quiet", "--check"}) {
    EXPECT_NE(run_help.find(o), std::string::npos) << o;
    EXPECT_NE(render_help.find(o), std::string::npos) << o;
  }
}

TEST(CliCommandLine, OtherProgramsHelpOnStdout) {
  const auto vda = test::run_command("(" + test::program("dvs-weights") + " make-vda --help 2>/dev/null)");
  EXPECT_EQ(vda.exit_code, 0) << vda.output;
  EXPECT_NE(vda.output.find("make-vda"), std::string::npos) << vda.output;
  // In the build tree dvs-bench is bench/dvs-bench; a relocated bundle (DVS_BIN_DIR) holds it beside dvs.
  std::string bench = test::program("bench/dvs-bench");
  if (!fs::exists(bench)) bench = test::program("dvs-bench");
  if (!fs::exists(bench)) GTEST_SKIP() << "dvs-bench is not built here (DVS_BUILD_BENCH)";
  const auto b = test::run_command("(" + bench + " --help 2>/dev/null)");
  EXPECT_EQ(b.exit_code, 0) << b.output;
  EXPECT_NE(b.output.find("usage: dvs-bench"), std::string::npos) << b.output;
  const auto wrong = test::run_command("(" + bench + " --bogus 2>&1 >/dev/null)");
  EXPECT_EQ(wrong.exit_code, 2) << wrong.output;
  EXPECT_NE(wrong.output.find("--bogus"), std::string::npos) << wrong.output;
}

TEST(CliCommandLine, RenderTakesRunsInputOptionsAndTheyAct) {
  RenderInputs in;
  // --height/--width set the working size (the clip is 48x64).
  const auto sized = test::run_command(in.render(in.dir / "sized", "--height 32 --width 40 --quiet"));
  ASSERT_EQ(sized.exit_code, 0) << sized.output;
  EXPECT_EQ(read_npy(in.dir / "sized" / "mask.npy").shape, (Shape{5, 32, 40}));
  EXPECT_NE(sized.output.find("at 32x40 (HxW)"), std::string::npos) << sized.output;
  // --quiet: no progress lines on stderr (small working sizes: the forced-limits CI pass cannot splat 480x720).
  const auto quiet = test::run_command(in.render(in.dir / "q", "--height 32 --width 40 --quiet 2>&1 >/dev/null"));
  EXPECT_EQ(quiet.exit_code, 0);
  EXPECT_EQ(quiet.output, "") << quiet.output;
  const auto chatty = test::run_command(in.render(in.dir / "c", "--height 32 --width 40 2>&1 >/dev/null"));
  EXPECT_EQ(chatty.exit_code, 0);
  EXPECT_NE(chatty.output, "");
  // --progress json: stdout is JSON Lines only, ending in the done event.
  const auto json = test::run_command(in.render(in.dir / "j", "--height 32 --width 40 --progress json 2>/dev/null"));
  ASSERT_EQ(json.exit_code, 0) << json.output;
  std::istringstream lines(json.output);
  nlohmann::json last;
  int events = 0;
  for (std::string line; std::getline(lines, line); ++events) ASSERT_NO_THROW(last = nlohmann::json::parse(line)) << line;
  EXPECT_GT(events, 1);
  EXPECT_EQ(last["event"], "done");
  // --check: the preflight alone; nothing is written, a problem is a failure (1).
  const auto check = test::run_command(in.render(in.dir / "checked", "--height 32 --width 40 --check"));
  EXPECT_EQ(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("preflight: no problem found"), std::string::npos) << check.output;
  EXPECT_FALSE(fs::exists(in.dir / "checked"));
  const auto bad = test::run_command(in.render(in.dir / "bad", "--check --trajectory nowhere"));
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("nowhere"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(in.dir / "bad"));
}

TEST(CliCommandLine, BatchJobKeysAreRunsOptions) {
  test::PipelineInputs in;
  const auto jobs = in.dir / "jobs.jsonl";
  test::write_text(jobs, "# a comment\n{\"prompt\": \"a\", \"out\": \"" + (in.dir / "a").string() + "\"}\n" +
                             "{\"prompt\": \"b\", \"out\": \"" + (in.dir / "b").string() + "\", \"colour\": \"red\"}\n" +
                             "{\"prompt\": \"c\", \"out\": \"" + (in.dir / "c").string() + "\", \"vae-tiling\": \"yes\"}\n");
  const auto r = test::run_command(kDvs + " batch " + jobs.string() + in.inputs() + " --quiet");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("job 1 (jobs.jsonl:3): unknown key \"colour\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("job 2 (jobs.jsonl:4): \"vae-tiling\" is a flag"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("no job was run"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(in.dir / "a" / "output.mp4"));
}

TEST(CliCommandLine, DemoIntoAFileIsAClearError) {
  test::TempDir d;
  test::write_text(d / "a_file", "x");
  const auto r = test::run_command(kDvs + " demo --quiet --out " + (d / "a_file").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("a_file: exists and is not a folder"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("internal error"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace dvs
