#include "support/gpu.hpp"

#include <cstdlib>
#include <memory>

namespace dvs::test {

vk::Context& gpu() {
  static std::unique_ptr<vk::Context> ctx = [] {
    vk::ContextOptions o;
    o.validation = true;
    o.pipeline_cache_file = "-";  // tests exercise the disk cache explicitly
    return std::make_unique<vk::Context>(o);
  }();
  return *ctx;
}

void GpuTest::SetUp() { gpu().clear_validation_messages(); }

void GpuTest::TearDown() {
  auto msgs = gpu().validation_messages();
  EXPECT_TRUE(msgs.empty()) << msgs.size() << " validation message(s), first: " << (msgs.empty() ? "" : msgs[0]);
}

std::string golden_dir() {
  const char* env = std::getenv("DVS_GOLDEN_DIR");
  return env && *env ? env : DVS_DEFAULT_GOLDEN_DIR;
}

}  // namespace dvs::test
