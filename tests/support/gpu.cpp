#include "support/gpu.hpp"

#include <cstdlib>
#include <memory>
#include <string>

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

void GpuTest::SetUp() { gpu().clear_validation_messages(); }

void GpuTest::TearDown() {
  auto msgs = gpu().validation_messages();
  EXPECT_TRUE(msgs.empty()) << msgs.size() << " validation message(s), first: " << (msgs.empty() ? "" : msgs[0]);
}

bool sync_validation_enabled() {
  const char* e = std::getenv("VK_LAYER_ENABLES");
  return e && std::string(e).find("VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT") != std::string::npos;
}

std::string golden_dir() {
  const char* env = std::getenv("DVS_GOLDEN_DIR");
  return env && *env ? env : DVS_DEFAULT_GOLDEN_DIR;
}

}  // namespace dvs::test
