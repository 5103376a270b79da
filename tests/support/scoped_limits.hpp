// Forces lower device limits on the shared test context for one scope (as DVS_LIMITS would for a whole
// process), so a test can take an op's split paths at tiny sizes: ScopedLimits l(ctx(), "binding=4KiB").
#pragma once
#include <string>

#include "vk/context.hpp"
#include "vk/device_limits.hpp"

namespace dvs::test {

class ScopedLimits {
 public:
  ScopedLimits(vk::Context& ctx, const std::string& spec) : ctx_(ctx) {
    ctx_.override_limits(vk::parse_limit_overrides(spec, "ScopedLimits"));
  }
  ~ScopedLimits() { ctx_.override_limits({}); }
  ScopedLimits(const ScopedLimits&) = delete;
  ScopedLimits& operator=(const ScopedLimits&) = delete;

 private:
  vk::Context& ctx_;
};

}  // namespace dvs::test
