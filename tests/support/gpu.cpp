#include "support/gpu.hpp"

#include <cstdlib>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>

namespace dvs::test {

namespace {
bool g_gpu_made = false;  // gpu() has made the shared context (its census exists)
}  // namespace

vk::Context& gpu() {
  static std::unique_ptr<vk::Context> ctx = [] {
    vk::ContextOptions o;
    o.validation = true;
    o.pipeline_cache_file = "-";  // tests exercise the disk cache explicitly
    auto made = std::make_unique<vk::Context>(o);
    g_gpu_made = true;
    return made;
  }();
  return *ctx;
}

namespace {

using Notes = std::map<vk::Context::KernelNote, uint64_t>;
Notes g_notes_at_setup;  // the context's kernel census when the running test began

// Every test, a GpuTest or not, starts its census afresh (kernels_run_in_test), without making the context.
class CensusAtTestStart : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override { g_notes_at_setup = g_gpu_made ? gpu().kernel_notes() : Notes{}; }
};
const bool g_census_listener = [] {
  ::testing::UnitTest::GetInstance()->listeners().Append(new CensusAtTestStart);
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
  if (!g_gpu_made) return ran;
  for (const auto& [note, calls] : gpu().kernel_notes()) {
    auto before = g_notes_at_setup.find(note);
    if (calls > (before == g_notes_at_setup.end() ? 0 : before->second)) ran.push_back(note);
  }
  return ran;
}

std::string golden_dir() {
  const char* env = std::getenv("DVS_GOLDEN_DIR");
  return env && *env ? env : DVS_DEFAULT_GOLDEN_DIR;
}

}  // namespace dvs::test
