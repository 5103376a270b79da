// dvs/dvs.h: version, last error (c_api_guard.cpp) and the context calls over dvs::Context.
#include <algorithm>

#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"

using namespace dvs::capi;

extern "C" {

const char* dvs_version(void) { return DVS_VERSION; }

dvs_status dvs_context_create(const char* device, int32_t validation, dvs_context** out) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    require(out, "dvs_context_create", "out");
    *out = nullptr;
    dvs::ContextOptions o;
    o.device = device ? device : "";
    o.validation = validation != 0;
    auto handle = std::make_unique<dvs_context>();
    handle->context = std::make_unique<dvs::Context>(o);
    *out = handle.release();
  });
}

dvs_status dvs_context_create_on_host(const dvs_host_device* host, dvs_context** out) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    const char* call = "dvs_context_create_on_host";
    require(out, call, "out");
    *out = nullptr;
    require(host, call, "host");
    if (!host->lock_queue != !host->unlock_queue)
      throw dvs::UsageError(std::string(call) + ": host->lock_queue and host->unlock_queue must be both set or both NULL");
    dvs::HostDevice h;
    h.instance = host->instance;
    h.physical_device = host->physical_device;
    h.device = host->device;
    h.queue_family = host->queue_family;
    h.queue = host->queue;
    h.instance_api_version = host->instance_api_version;
    h.enabled_features = host->enabled_features;
    if (host->enabled_extension_count) require(host->enabled_extensions, call, "host->enabled_extensions");
    for (uint32_t i = 0; i < host->enabled_extension_count; ++i) {
      require(host->enabled_extensions[i], call, "an entry of host->enabled_extensions");
      h.enabled_extensions.push_back(host->enabled_extensions[i]);
    }
    if (host->lock_queue) {
      h.lock_queue = [f = host->lock_queue, user = host->user_data] { f(user); };
      h.unlock_queue = [f = host->unlock_queue, user = host->user_data] { f(user); };
    }
    auto handle = std::make_unique<dvs_context>();
    handle->context = std::make_unique<dvs::Context>(h);
    *out = handle.release();
  });
}

dvs_status dvs_context_destroy(dvs_context* context) {
  return guarded(DVS_ERROR_DEVICE, [&] { delete context; });
}

dvs_status dvs_context_device_name(const dvs_context* context, char* buffer, size_t size, size_t* needed) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    require(context, "dvs_context_device_name", "context");
    copy_out(context->context->device_name(), buffer, size, needed, "dvs_context_device_name", "buffer");
  });
}

dvs_status dvs_context_timeline(const dvs_context* context, VkSemaphore* out) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    require(context, "dvs_context_timeline", "context");
    require(out, "dvs_context_timeline", "out");
    *out = context->context->timeline();
  });
}

dvs_status dvs_context_requirements(int32_t optional, char* buffer, size_t size, size_t* needed) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    std::string lines;
    for (const std::string& name : optional ? dvs::Context::optional_features() : dvs::Context::required_features())
      lines += name + "\n";
    copy_out(lines, buffer, size, needed, "dvs_context_requirements", "buffer");
  });
}

dvs_status dvs_context_wait(const dvs_context* context, uint64_t ticket, uint64_t timeout_ns, int32_t* reached) {
  return guarded(DVS_ERROR_DEVICE, [&] {
    require(context, "dvs_context_wait", "context");
    const bool done = context->context->wait(ticket, timeout_ns);
    if (reached) *reached = done ? 1 : 0;
  });
}

}  // extern "C"
