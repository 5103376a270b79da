// What every dvs command shares (issue 12, item 8): --help exits 0, usage errors 2, failures 1, interruption
// 130; --progress json keeps stdout pure JSON Lines ending in a done/error event; the libraries' log lines
// stay hidden unless --verbose; a full disk is named; --prompt "" works and a long prompt is warned about;
// two SIGINTs arriving together are one Ctrl-C.
#include <gtest/gtest.h>

#include <signal.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
const std::string kDvs = test::program("dvs");
const std::string kTool = test::program("dvs-weights");

TEST(CliConventions, HelpExitsZeroEverywhere) {
  for (const char* cmd : {"", "info", "render", "run", "demo", "invert", "encode-prompt", "batch", "plan", "depth", "cache"}) {
    const auto r = test::run_command(kDvs + " " + cmd + " --help");
    EXPECT_EQ(r.exit_code, 0) << "dvs " << cmd << " --help\n" << r.output;
    EXPECT_NE(r.output.find("usage"), std::string::npos) << "dvs " << cmd << " --help\n" << r.output;
  }
  for (const char* cmd : {"", "inspect", "make-tiny", "make-vda", "merge-lora"}) {
    const auto r = test::run_command(kTool + " " + cmd + " --help");
    EXPECT_EQ(r.exit_code, 0) << "dvs-weights " << cmd << " --help\n" << r.output;
  }
}

TEST(CliConventions, UsageErrorsExitTwoFailuresOne) {
  test::TempDir d;
  for (const std::string args : {"frobnicate", "info --bogus", "render --bogus 1", "render --video v.mp4",
                                 "render --video v.mp4 --depth d.npy --out o --size 48", "plan --model m --frames x",
                                 "plan --model m --budget lots", "run --video v --depth d --model m --out o",
                                 "run --progress xml --video v --depth d --model m --out o --prompt p",
                                 "render --video v.mp4 --depth d.npy --out o --resize sideways"}) {
    const auto r = test::run_command(kDvs + " " + args);
    EXPECT_EQ(r.exit_code, 2) << "dvs " << args << "\n" << r.output;
    EXPECT_NE(r.output.find("--help"), std::string::npos) << "dvs " << args << "\n" << r.output;
  }
  // The command line is fine, the work fails: 1.
  const auto missing = test::run_command(kDvs + " render --video " + (d / "none.mp4").string() + " --depth " +
                                         (d / "none.npy").string() + " --out " + (d / "o").string());
  EXPECT_EQ(missing.exit_code, 1) << missing.output;
}

// Every stdout line of a --progress json run is a JSON object; the last is the final event.
std::vector<nlohmann::json> json_lines(const std::string& text) {
  std::vector<nlohmann::json> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    try {
      out.push_back(nlohmann::json::parse(line));
    } catch (const nlohmann::json::exception&) {
      ADD_FAILURE() << "not JSON on stdout: '" << line << "'";
    }
  }
  return out;
}

TEST(CliConventions, JsonProgressIsPureJsonLinesWithAFinalEventEmptyPromptAndLongPromptWarning) {
  test::PipelineInputs in;
  const auto out = in.dir / "out", so = in.dir / "stdout.jsonl", se = in.dir / "stderr.txt";
  // The pack's model reads 8 tokens: this negative prompt is longer. The prompt itself is empty.
  const std::string cmd = kDvs + " run" + in.inputs() + " --progress json --out " + out.string() +
                          " --prompt '' --negative-prompt 'blurry, low quality, distorted faces, watermark, text'";
  const auto r = test::run_command("(" + cmd + " > " + so.string() + " 2> " + se.string() + ")");
  const std::string err = test::read_text(se);
  ASSERT_EQ(r.exit_code, 0) << err;
  const auto events = json_lines(test::read_text(so));
  ASSERT_GE(events.size(), 2u);
  EXPECT_EQ(events.front()["event"], "progress");
  EXPECT_EQ(events.back()["event"], "done");
  EXPECT_EQ(events.back()["exit_code"], 0);
  for (size_t i = 0; i + 1 < events.size(); ++i) EXPECT_EQ(events[i]["event"], "progress") << events[i].dump();
  // The plain lines went to stderr.
  EXPECT_NE(err.find("wrote " + (out / "output.mp4").string()), std::string::npos) << err;
  EXPECT_NE(err.find("warning: --negative-prompt is"), std::string::npos) << err;
  EXPECT_NE(err.find("this model reads 8"), std::string::npos) << err;
  EXPECT_EQ(err.find("warning: --prompt"), std::string::npos) << err;

  // A failing run: still pure JSON Lines, ending in an error event with the exit code and the message.
  const auto bad = test::run_command("(" + kDvs + " run" + in.inputs() + " --progress json --prompt x " +
                                     "--depth " + (in.dir / "none.npy").string() + " --out " + (in.dir / "bad").string() +
                                     " > " + so.string() + " 2> " + se.string() + ")");
  EXPECT_EQ(bad.exit_code, 1) << test::read_text(se);
  const auto bad_events = json_lines(test::read_text(so));
  ASSERT_FALSE(bad_events.empty());
  EXPECT_EQ(bad_events.back()["event"], "error");
  EXPECT_EQ(bad_events.back()["exit_code"], 1);
  EXPECT_NE(bad_events.back()["message"].get<std::string>().find("none.npy"), std::string::npos) << bad_events.back().dump();
  // A usage error too.
  const auto usage = test::run_command("(" + kDvs + " run --progress json --bogus > " + so.string() + " 2> /dev/null)");
  EXPECT_EQ(usage.exit_code, 2);
  const auto usage_events = json_lines(test::read_text(so));
  ASSERT_EQ(usage_events.size(), 1u);
  EXPECT_EQ(usage_events[0]["event"], "error");
  EXPECT_EQ(usage_events[0]["exit_code"], 2);
}

TEST(CliConventions, ThirdPartyLogLinesOnlyWithVerbose) {
  test::TempDir d;
  // SentencePiece's trainer (make-tiny writes the tokenizer) prints its command line on stderr.
  const auto quiet = test::run_command(kTool + " make-tiny --layers 1 --t5-layers 1 --out " + (d / "m").string());
  ASSERT_EQ(quiet.exit_code, 0) << quiet.output;
  EXPECT_EQ(quiet.output.find("LOG(INFO)"), std::string::npos) << quiet.output;
  const auto verbose = test::run_command(kTool + " make-tiny --verbose --layers 1 --t5-layers 1 --out " + (d / "v").string());
  ASSERT_EQ(verbose.exit_code, 0) << verbose.output;
  EXPECT_NE(verbose.output.find("LOG(INFO)"), std::string::npos) << verbose.output;

  // FFmpeg's own complaint about a truncated MP4: dvs says what is wrong in its words only.
  HostTensor rgb({3, 3, 16, 16}, DType::f32);
  write_video(d / "ok.mp4", rgb, 10);
  std::string bytes = test::read_text(d / "ok.mp4");
  test::write_text(d / "cut.mp4", bytes.substr(0, bytes.size() / 3));
  HostTensor depth({3, 16, 16}, DType::f32);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = 1.0f + float(i % 5);
  write_npy(d / "d.npy", depth);
  const std::string render = " render --video " + (d / "cut.mp4").string() + " --depth " + (d / "d.npy").string() +
                             " --size 16x16 --out " + (d / "o").string();
  const auto r = test::run_command(kDvs + render);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cut.mp4"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find(" @ 0x"), std::string::npos) << r.output;  // FFmpeg's "[mov,mp4,… @ 0x…]" prefix
  const auto rv = test::run_command(kDvs + " --verbose" + render);
  EXPECT_EQ(rv.exit_code, 1) << rv.output;
  EXPECT_NE(rv.output.find(" @ 0x"), std::string::npos) << rv.output;
}

// A full disk: `dvs render` into a 16 KiB file system (a private tmpfs in a user + mount namespace).
TEST(CliConventions, FullDiskIsNamed) {
  if (test::run_command("unshare -rm true").exit_code != 0)
    GTEST_SKIP() << "unshare -rm (user and mount namespaces) is not available here: cannot make a full disk";
  test::TempDir d;
  HostTensor rgb({5, 3, 48, 64}, DType::f32);
  for (int64_t i = 0; i < rgb.numel(); ++i) rgb.as<float>()[i] = float((i * 7919) % 200) / 100.0f - 1.0f;
  write_video(d / "v.mp4", rgb, 10);
  HostTensor depth({5, 48, 64}, DType::f32);
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = 2.0f + float(i % 13) * 0.1f;
  write_npy(d / "d.npy", depth);
  fs::create_directories(d / "small");
  const std::string render = kDvs + " render --video " + (d / "v.mp4").string() + " --depth " + (d / "d.npy").string() +
                             " --metric-depth --size 48x64 --frames 5 --out " + (d / "small" / "out").string();
  const auto r = test::run_command("unshare -rm sh -c 'mount -t tmpfs -o size=16k tmpfs " + (d / "small").string() +
                                   " && " + render + "'");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("no space left on device"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("is the folder writable"), std::string::npos) << r.output;
}

// `timeout -s INT` and some terminals deliver two SIGINTs at once: still one clean stop.
TEST(CliConventions, TwoSigintsTogetherAreOneCleanInterrupt) {
  test::PipelineInputs in;
  const auto out = in.dir / "out", log = in.dir / "log.txt";
  const int pid = test::start_command(in.command(out, "--steps 400 --inversion-steps 400 --no-cache > " + log.string() + " 2>&1"));
  ASSERT_GT(pid, 0);
  bool inverting = false;
  for (int i = 0; i < 6000 && !inverting; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    inverting = test::read_text(log).find("\"stage\":\"invert\",\"step\":1,") != std::string::npos;
  }
  ASSERT_TRUE(inverting) << test::read_text(log);
  kill(pid, SIGINT);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  kill(pid, SIGINT);
  EXPECT_EQ(test::wait_command(pid), 130);
  const std::string output = test::read_text(log);
  EXPECT_NE(output.find("interrupted; partial outputs removed"), std::string::npos) << output;
  EXPECT_NE(output.find("\"event\":\"error\""), std::string::npos) << output;
  for (const auto& name : test::files_in(out)) ADD_FAILURE() << "left in the output folder: " << name;
}

}  // namespace
}  // namespace dvs
