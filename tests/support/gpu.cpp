#include "support/gpu.hpp"

#include <cstdlib>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <string>

#include "support/files.hpp"
#include "vk/validation_log.hpp"

namespace dvs::test {

namespace {

std::unique_ptr<vk::Context>& shared_context() {
  static std::unique_ptr<vk::Context> ctx;
  return ctx;
}

// The shared context goes when the tests are done, before main returns. Left to the exit handlers, it was destroyed
// after static objects the validation layer makes at first use (so after this context was made, and destroyed
// before it), and its vkDeviceWaitIdle ran into them: with the layer's QueueSubmit check on, that call never
// returned and the program hung after printing its summary.
class ReleaseSharedContext : public ::testing::Environment {
 public:
  void TearDown() override { shared_context().reset(); }
};
::testing::Environment* const kReleaseSharedContext = ::testing::AddGlobalTestEnvironment(new ReleaseSharedContext);

}  // namespace

vk::Context& gpu() {
  std::unique_ptr<vk::Context>& ctx = shared_context();
  if (!ctx) {
    vk::ContextOptions o;
    o.validation = true;
    o.pipeline_cache_file = "-";  // tests exercise the disk cache explicitly
    ctx = std::make_unique<vk::Context>(o);
  }
  return *ctx;
}

namespace {

using Notes = std::map<vk::Context::KernelNote, uint64_t>;
Notes g_notes_at_setup;  // the context's kernel census when the running test began

// Every test, a GpuTest or not, starts its census afresh (kernels_run_in_test), without making the context.
class CensusAtTestStart : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override { g_notes_at_setup = shared_context() ? gpu().kernel_notes() : Notes{}; }
};
// A validation message that arrived during a test and that nothing in the test read and cleared fails it, whichever
// context received it (vk/validation_log.hpp): a test of the public API makes contexts that no check of its own
// reads. Listeners hear a test's end in reverse order, so this failure counts before the result is printed.
class UnreadValidationMessagesFailTheTest : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override { vk::validation_log::mark(); }
  void OnTestEnd(const ::testing::TestInfo&) override {
    const std::vector<std::string> unread = vk::validation_log::unread();
    if (!unread.empty())
      ADD_FAILURE() << unread.size() << " validation message(s) during the test that no check in it read, first: "
                    << unread[0];
  }
};
const bool g_census_listener = [] {
  ::testing::UnitTest::GetInstance()->listeners().Append(new CensusAtTestStart);
  ::testing::UnitTest::GetInstance()->listeners().Append(new UnreadValidationMessagesFailTheTest);
  return true;
}();

// DVS_REQUIRE_COOPMAT (the tensor-core pass, tests/run_coopmat_pass.sh): the ops, comma-separated, that must have
// run on tensor cores by the end of the program; while it is set, a test whose calls fell back from a coopmat
// family for a reason of the device fails.
std::set<std::string> required_coopmat_ops() {
  const char* e = std::getenv("DVS_REQUIRE_COOPMAT");
  std::set<std::string> ops;
  if (!e) return ops;
  std::stringstream ss(e);
  for (std::string op; std::getline(ss, op, ',');)
    if (!op.empty()) ops.insert(op);
  return ops;
}

std::string note_text(const vk::Context::KernelNote& n, uint64_t calls) {
  return n.op + ": " + n.shader + " (" + n.family + ") x" + std::to_string(calls) +
         (n.fallback.empty() ? "" : (n.device ? ", device fallback: " : ", call fallback: ") + n.fallback);
}

// At the end of the program, under DVS_REQUIRE_COOPMAT: the census, and a failure for every op required that
// never ran on tensor cores.
class CoopmatCensus : public ::testing::Environment {
 public:
  void TearDown() override {
    const std::set<std::string> required = required_coopmat_ops();
    if (required.empty()) return;
    std::map<std::string, uint64_t> coopmat_calls;
    std::cout << "kernel census (calls per op and kernel, DVS_REQUIRE_COOPMAT=" << std::getenv("DVS_REQUIRE_COOPMAT")
              << "):\n";
    for (const auto& [note, calls] : gpu().kernel_notes()) {
      std::cout << "  " << note_text(note, calls) << "\n";
      if (note.family == "coopmat") coopmat_calls[note.op] += calls;
    }
    for (const std::string& op : required)
      EXPECT_GT(coopmat_calls[op], 0u) << op << " never ran a tensor-core (coopmat) kernel in this program";
  }
};
const auto* const g_census = ::testing::AddGlobalTestEnvironment(new CoopmatCensus);

}  // namespace

void GpuTest::SetUp() {
  gpu().clear_validation_messages();
  g_notes_at_setup = gpu().kernel_notes();
}

void GpuTest::TearDown() {
  auto msgs = gpu().validation_messages();
  EXPECT_TRUE(msgs.empty()) << msgs.size() << " validation message(s), first: " << (msgs.empty() ? "" : msgs[0]);
  gpu().clear_validation_messages();  // read (once reported here, not again by the unread-message check)
  if (required_coopmat_ops().empty()) return;
  for (const auto& [note, calls] : gpu().kernel_notes()) {
    auto before = g_notes_at_setup.find(note);
    const uint64_t here = calls - (before == g_notes_at_setup.end() ? 0 : before->second);
    EXPECT_FALSE(here > 0 && note.device) << "a call fell back from tensor cores for a reason of the device "
                                          << "(DVS_REQUIRE_COOPMAT): " << note_text(note, here);
  }
}

void forgive_kernel_fallbacks() { g_notes_at_setup = gpu().kernel_notes(); }

std::vector<vk::Context::KernelNote> kernels_run_in_test() {
  std::vector<vk::Context::KernelNote> ran;
  if (!shared_context()) return ran;
  for (const auto& [note, calls] : gpu().kernel_notes()) {
    auto before = g_notes_at_setup.find(note);
    if (calls > (before == g_notes_at_setup.end() ? 0 : before->second)) ran.push_back(note);
  }
  return ran;
}

bool sync_validation_enabled() {
  const char* e = std::getenv("VK_LAYER_ENABLES");
  return e && std::string(e).find("VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT") != std::string::npos;
}

std::string golden_dir() { return golden_path().string(); }

}  // namespace dvs::test
