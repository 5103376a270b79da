// dvs/context.hpp over vk::Context: dvs's own device, or the application's (HostDevice, checked by
// vk/host_device.hpp). Tickets are values of vk::Context's timeline semaphore. The device objects live in a
// ContextCore shared with what is made on the context; its gate serialises the calls (embed/context_gate.hpp).
#include "dvs/context.hpp"

#include "dvs/error.hpp"
#include "embed/context_core.hpp"
#include "embed/public_call.hpp"
#include "pipeline/public_limits.hpp"
#include "vk/context.hpp"
#include "vk/host_device.hpp"

namespace dvs {

struct Context::Impl {
  std::shared_ptr<embed::ContextCore> core;
};

namespace {
vk::ContextOptions internal_options(const ContextOptions& o) {
  vk::ContextOptions v;
  v.device = o.device;
  v.validation = o.validation;
  v.pipeline_cache_file = o.pipeline_cache_file;
  return v;
}

// A context that cannot be made is the device's problem (no driver, no such device, a missing feature), unless an
// argument was refused or memory ran out.
template <class Make>
std::shared_ptr<embed::ContextCore> make_core(const char* call, Make make) {
  return embed::public_call(call, [&] {
    auto core = std::make_shared<embed::ContextCore>();
    try {
      core->device = make();
    } catch (const Error& e) {
      if (e.kind() != ErrorKind::input) throw;
      throw Error(e.what(), ErrorKind::device);
    }
    return core;
  });
}
}  // namespace

Context::Context(const ContextOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->core = make_core("dvs::Context", [&] { return std::make_unique<vk::Context>(internal_options(options)); });
}

Context::Context(const HostDevice& host, const ContextOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->core =
      make_core("dvs::Context(HostDevice)", [&] { return std::make_unique<vk::Context>(host, internal_options(options)); });
}

// The job is stopped here; the device objects stay while a scene or estimator made on the context holds them.
Context::~Context() { impl_->core->gate.cancel_and_wait_for_job(); }

std::vector<std::string> Context::required_features() { return vk::host_device_requirements(); }
std::vector<std::string> Context::optional_features() { return vk::host_device_options(); }

// Set when the context is made and never changed: no turn at the gate needed.
std::string Context::device_name() const { return impl_->core->device->caps().name; }
DeviceLimits Context::limits() const { return limits_of(impl_->core->device->caps()); }
bool Context::owns_device() const { return impl_->core->device->owns_device(); }
VkSemaphore Context::timeline() const { return impl_->core->device->timeline(); }

uint64_t Context::submitted_value() const {
  embed::ContextCore& c = *impl_->core;
  return embed::public_call("dvs::Context::submitted_value", [&] {
    embed::GateUse use(c.gate, "dvs::Context::submitted_value");
    return c.device->submission_count();
  });
}

bool Context::wait(uint64_t ticket, uint64_t timeout_ns) const {
  embed::ContextCore& c = *impl_->core;
  return embed::public_call("dvs::Context::wait", [&] {
    embed::GateUse use(c.gate, "dvs::Context::wait");
    return c.device->wait(ticket, timeout_ns);
  });
}

void Context::wait_before_next(VkSemaphore semaphore, uint64_t value) {
  embed::ContextCore& c = *impl_->core;
  embed::public_call("dvs::Context::wait_before_next", [&] {
    embed::GateUse use(c.gate, "dvs::Context::wait_before_next");
    c.device->wait_before_next(semaphore, value);
  });
}

vk::Context& Context::internal() { return *impl_->core->device; }
std::shared_ptr<embed::ContextCore> Context::core() const { return impl_->core; }

}  // namespace dvs
