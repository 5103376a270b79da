// dvs/context.hpp over vk::Context. This first form runs on dvs's own device only; the application's device
// (HostDevice) and the timeline semaphore are issue 22's next step.
#include "dvs/context.hpp"

#include "dvs/error.hpp"
#include "embed/public_limits.hpp"
#include "vk/context.hpp"

namespace dvs {

struct Context::Impl {
  std::unique_ptr<vk::Context> ctx;
};

namespace {
vk::ContextOptions internal_options(const ContextOptions& o) {
  vk::ContextOptions v;
  v.device = o.device;
  v.validation = o.validation;
  v.pipeline_cache_file = o.pipeline_cache_file;
  return v;
}
}  // namespace

Context::Context(const ContextOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->ctx = std::make_unique<vk::Context>(internal_options(options));
}

Context::Context(const HostDevice&, const ContextOptions&) {
  throw Error("dvs::Context on the application's device is not implemented yet");
}

Context::~Context() = default;

std::vector<std::string> Context::required_features() { return {"Vulkan 1.2", "timelineSemaphore"}; }
std::vector<std::string> Context::optional_features() { return {}; }

std::string Context::device_name() const { return impl_->ctx->caps().name; }
DeviceLimits Context::limits() const { return limits_of(impl_->ctx->caps()); }
bool Context::owns_device() const { return true; }
VkSemaphore Context::timeline() const { return VK_NULL_HANDLE; }
uint64_t Context::submitted_value() const { return impl_->ctx->submission_count(); }
bool Context::wait(uint64_t, uint64_t) const { return true; }  // every submission is waited for today
void Context::wait_before_next(VkSemaphore, uint64_t) {
  throw Error("dvs::Context::wait_before_next is not implemented yet");
}
vk::Context& Context::internal() { return *impl_->ctx; }

}  // namespace dvs
