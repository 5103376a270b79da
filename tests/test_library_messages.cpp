// The library's own messages (issue 34): warnings go to the application's log handler (dvs/logs.hpp), not straight
// to stderr; messages name an option by its field (RunOptions::steps) in the library and by its flag (--steps) in the
// dvs program (dvs/option_names.hpp); a negative number where 0 means "the preset's default" is refused, naming the
// field, instead of quietly becoming the default.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

#include "dvs/depth_estimate.hpp"
#include "dvs/error.hpp"
#include "dvs/job.hpp"
#include "dvs/logs.hpp"
#include "dvs/option_names.hpp"
#include "dvs/plan.hpp"
#include "dvs/preflight.hpp"
#include "dvs/trajectory.hpp"
#include "io/host_tensor.hpp"
#include "io/option_names.hpp"
#include "pipeline/render_stage.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/random_vda.hpp"

namespace dvs {
namespace {

// Collects what the library logs while alive; the default handler again afterwards.
struct CapturedLog {
  std::mutex m;
  std::vector<std::string> messages;
  CapturedLog() {
    set_log_handler([this](LogLevel level, const std::string& message) {
      EXPECT_EQ(level, LogLevel::warning);
      const std::lock_guard<std::mutex> lock(m);
      messages.push_back(message);
    });
  }
  ~CapturedLog() { set_log_handler({}); }
};

// The authors' format with lines of different lengths loads, with a warning: to the handler, else to stderr.
TEST(LibraryMessages, WarningsReachTheLogHandlerAndOtherwiseStderr) {
  test::TempDir d;
  test::write_text(d / "uneven.txt", "0 5 10\n0 -3\n0 0 0 0\n");
  const std::string file = (d / "uneven.txt").string();
  {
    CapturedLog log;
    testing::internal::CaptureStderr();
    EXPECT_EQ(load_trajectory(file, 5, 1.0).size(), 5u);
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "") << "a handler is installed: nothing on stderr";
    ASSERT_EQ(log.messages.size(), 1u);
    EXPECT_EQ(log.messages[0].rfind(file + ": its lines hold different numbers of values", 0), 0u) << log.messages[0];
  }
  testing::internal::CaptureStderr();
  load_trajectory(file, 5, 1.0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err.rfind("dvs: warning: " + file + ": its lines hold different numbers of values", 0), 0u) << err;
}

// A path that shows nothing in some frames: a warning naming the path as the job names it and where the user sees
// the mask (a clip run writes no mask.mp4).
TEST(LibraryMessages, EmptyFramesNameThePathAndWhereTheMaskIs) {
  const std::vector<float> visible{1, 1, 1, 1, 0, 0, 0, 0, 0, 1, 0, 0};  // frame 1 empty
  const HostTensor mask = HostTensor::from_f32({3, 2, 2}, visible);
  RenderJob job;
  job.trajectory = "pan_left:90";
  CapturedLog log;
  const auto progress = [](const std::string&) {};
  check_visibility(mask, job, 1.0, progress, "mask.mp4");
  job.trajectory = "ClipView::poses";  // what a clip run with poses in memory names its path
  check_visibility(mask, job, 1.0, progress, "the mask view");
  ASSERT_EQ(log.messages.size(), 2u);
  EXPECT_EQ(log.messages[0], "RenderJob::trajectory pan_left:90: frame 1 (1 of 3) show nothing of the scene (0% of the "
                             "pixels visible); the model has to invent them. Look at mask.mp4, or use a smaller move");
  EXPECT_EQ(log.messages[1].rfind("ClipView::poses: frame 1 (1 of 3) show nothing", 0), 0u) << log.messages[1];
  EXPECT_NE(log.messages[1].find("Look at the mask view"), std::string::npos) << log.messages[1];
}

// steps, strength, delta, inversion_steps: 0 is the preset's default, a negative value a problem naming the field
// (RunOptions::steps in the library, --steps when the dvs program asked for its flags).
TEST(LibraryMessages, NegativeNumbersAreRefusedNamingTheField) {
  test::PipelineInputs in;
  const RunOptions base = in.run_options(in.dir / "out", in.cache);
  auto problems_of = [](const RunOptions& o) {
    std::string all;
    for (const std::string& p : preflight(o, JobKind::run).problems) all += p + "\n";
    return all;
  };
  EXPECT_EQ(problems_of(base), "");
  RunOptions zeros = base;
  zeros.steps = 0, zeros.strength = 0, zeros.delta = 0, zeros.inversion_steps = 0;
  EXPECT_EQ(problems_of(zeros), "") << "0 is the preset's default";
  struct Case {
    void (*set)(RunOptions&);
    std::string field, value;
  };
  const std::vector<Case> cases{{[](RunOptions& o) { o.steps = -3; }, "steps", "-3"},
                                {[](RunOptions& o) { o.strength = -1; }, "strength", "-1"},
                                {[](RunOptions& o) { o.delta = -1; }, "delta", "-1"},
                                {[](RunOptions& o) { o.inversion_steps = -1; }, "inversion_steps", "-1"},
                                {[](RunOptions& o) { o.strength = std::nan(""); }, "strength", "nan"}};
  for (const Case& c : cases) {
    RunOptions o = base;
    c.set(o);
    const std::string all = problems_of(o);
    EXPECT_NE(all.find("RunOptions::" + c.field + " is " + c.value + ": give "), std::string::npos) << all;
    EXPECT_NE(all.find("or 0 for the preset's default"), std::string::npos) << all;
    set_option_names(OptionNames::command_line);
    const std::string flags = problems_of(o);
    set_option_names(OptionNames::fields);
    EXPECT_NE(flags.find(option_flag("RunOptions::" + c.field) + " is " + c.value), std::string::npos) << flags;
  }
}

// A depth job's numbers are refused before any work as argument errors naming DepthJob's fields (dvs depth's flags
// when the dvs program asked for them); in a run, the depth stage names the RenderJob fields (RunOptions above).
TEST(LibraryMessages, DepthJobRefusalsNameItsFields) {
  test::TempDir dir;
  DepthJob base;
  base.video = dir.path / "clip.mp4", base.model = dir.path / "vits.pth";
  std::ofstream(base.video) << "checked after the numbers";
  std::ofstream(base.model) << "checked after the numbers";
  auto refusal = [&](const DepthJob& job) {
    try {
      estimate_depth(job, dir.path / "depth.npz");
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::invalid_argument) << e.what();
      return std::string(e.what());
    }
    ADD_FAILURE() << "estimate_depth accepted the job";
    return std::string();
  };
  struct Case {
    void (*set)(DepthJob&);
    std::string field, text;
  };
  const std::vector<Case> cases{{[](DepthJob& j) { j.frames = -2; }, "frames", " must be ≥ 0 (0 = all frames), got -2"},
                                {[](DepthJob& j) { j.max_res = -1; }, "max_res", " must be ≥ 0 (0 = no limit), got -1"},
                                {[](DepthJob& j) { j.input_size = 13; }, "input_size", " must be in [14, 4096]"}};
  for (const Case& c : cases) {
    DepthJob j = base;
    c.set(j);
    const std::string library = refusal(j);
    EXPECT_EQ(library.rfind("DepthJob::" + c.field + c.text, 0), 0u) << library;
    set_option_names(OptionNames::command_line);
    const std::string program = refusal(j);
    set_option_names(OptionNames::fields);
    EXPECT_EQ(program.rfind(option_flag("DepthJob::" + c.field) + c.text, 0), 0u) << program;
    EXPECT_EQ(program.find("DepthJob::"), std::string::npos) << program;
  }
  DepthJob j = base;  // a run's depth stage names what its user set
  j.frames = -2, j.frames_option = option_name("RenderJob::frames");
  EXPECT_EQ(refusal(j).rfind("RenderJob::frames must be", 0), 0u);
  j = base;
  j.video = dir.path / "missing.mp4";
  try {
    estimate_depth(j, dir.path / "depth.npz");
    ADD_FAILURE() << "a missing video was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("(give DepthJob::video)"), std::string::npos) << e.what();
  }
}

// Advice that is no option's name speaks the caller's language too: an output path the library was given is
// not "--out", and a depth estimate's forecast is stopped by the cancel function, not Ctrl-C.
TEST(LibraryMessages, AdviceSpeaksTheCallersLanguage) {
  test::PipelineInputs in;
  const test::TempDir dir;
  DepthJob job;
  job.video = in.video, job.model = test::random_vda(dir.path / "vda");
  std::filesystem::create_directories(dir.path / "a-folder.npz");
  const auto message = [&] {
    try {
      estimate_depth(job, dir.path / "a-folder.npz");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    ADD_FAILURE() << "estimate_depth accepted a folder as its output file";
    return std::string();
  };
  const std::string library = message();
  EXPECT_NE(library.find("give another output path"), std::string::npos) << library;
  EXPECT_EQ(library.find("--out"), std::string::npos) << library;
  set_option_names(OptionNames::command_line);
  const std::string program = message();
  set_option_names(OptionNames::fields);
  EXPECT_NE(program.find("give another --out"), std::string::npos) << program;

  MemoryPlanRequest req;
  req.model = (dir.path / "no-model").string();
  try {
    plan_run_memory(req);
    ADD_FAILURE() << "plan_run_memory accepted a missing model folder";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("(give MemoryPlanRequest::model a folder"), std::string::npos) << e.what();
  }
}

// A job on files refuses its options when it starts (an unknown preset was the job's result, an input failure).
TEST(LibraryMessages, AJobOnFilesRefusesItsOptionsAtStart) {
  RunOptions o;
  o.preset = "fancy";
  try {
    start_pipeline(o);
    ADD_FAILURE() << "start_pipeline accepted preset 'fancy'";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::invalid_argument);
    EXPECT_EQ(std::string(e.what()), "RunOptions::preset must be paper or official, got 'fancy'");
  }
}

// The prompt the model cuts (the pack's model reads 8 tokens) is a preflight note naming the field.
TEST(LibraryMessages, ALongPromptIsAWarningNamingTheField) {
  test::PipelineInputs in;
  RunOptions o = in.run_options(in.dir / "out", in.cache);
  o.prompt = "a red fox jumps over the lazy brown dog in the snow";
  const PreflightReport r = preflight(o, JobKind::run);
  std::string notes;
  for (const std::string& n : r.notes) notes += n + "\n";
  EXPECT_NE(notes.find("warning: RunOptions::prompt is "), std::string::npos) << notes;
  EXPECT_NE(notes.find(" tokens but this model reads 8 (max_text_seq_length"), std::string::npos) << notes;
  EXPECT_EQ(notes.find("negative_prompt"), std::string::npos) << notes;
}

// Every flag the table names is one the dvs program declares (run, render, plan or depth --help lists it).
TEST(LibraryMessages, EveryFieldsFlagIsAProgramOption) {
  std::string help;
  for (const char* command : {"run", "render", "plan", "depth"})
    help += test::run_command(test::program("dvs") + std::string(" ") + command + " --help").output;
  for (const std::string& field : option_fields()) {
    const std::string flag = option_flag(field);
    const std::string word = flag.substr(0, flag.find(' '));
    EXPECT_NE(help.find(word + " "), std::string::npos) << field << " -> " << flag;
    EXPECT_EQ(option_name(field), field) << "the library names the field by default";
  }
  EXPECT_EQ(option_flag("RunOptions::render.trajectory"), "--trajectory");
  EXPECT_THROW(option_flag("RunOptions::no_such_field"), Error);
}

}  // namespace
}  // namespace dvs
