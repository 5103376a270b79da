// dvs/context.hpp over vk::Context: dvs's own device, or the application's (HostDevice, checked by
// vk/host_device.hpp). Tickets are values of vk::Context's timeline semaphore.
#include "dvs/context.hpp"

#include "dvs/error.hpp"
#include "pipeline/public_limits.hpp"
#include "vk/context.hpp"
#include "vk/host_device.hpp"

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

Context::Context(const HostDevice& host, const ContextOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->ctx = std::make_unique<vk::Context>(host, internal_options(options));
}

Context::~Context() = default;

std::vector<std::string> Context::required_features() { return vk::host_device_requirements(); }
std::vector<std::string> Context::optional_features() { return vk::host_device_options(); }

std::string Context::device_name() const { return impl_->ctx->caps().name; }
DeviceLimits Context::limits() const { return limits_of(impl_->ctx->caps()); }
bool Context::owns_device() const { return impl_->ctx->owns_device(); }
VkSemaphore Context::timeline() const { return impl_->ctx->timeline(); }
uint64_t Context::submitted_value() const { return impl_->ctx->submission_count(); }
bool Context::wait(uint64_t ticket, uint64_t timeout_ns) const { return impl_->ctx->wait(ticket, timeout_ns); }
void Context::wait_before_next(VkSemaphore semaphore, uint64_t value) {
  impl_->ctx->wait_before_next(semaphore, value);
}
vk::Context& Context::internal() { return *impl_->ctx; }

}  // namespace dvs
