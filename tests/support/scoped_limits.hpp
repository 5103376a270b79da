// Forces lower device limits on the shared test context for one scope (as DVS_LIMITS would for a whole
// process), so a test can take an op's split paths at tiny sizes: ScopedLimits l(ctx(), "binding=4KiB").
#pragma once
#include <cstdint>
#include <iostream>
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

// True (and says so) when a case needs a tensor of `bytes` over the allocation limit in force: a tensor is
// one allocation, so under a low DVS_LIMITS alloc such a case cannot even be uploaded and is left out.
inline bool over_allocation_limit(vk::Context& ctx, uint64_t bytes, const std::string& what) {
  if (bytes <= ctx.caps().max_memory_allocation_size) return false;
  std::cout << "[ SKIPPED  ] " << what << ": a tensor of " << bytes << " B over the allocation limit in force\n";
  return true;
}

}  // namespace dvs::test
