// dvs/dvs.h: the depth estimator calls over dvs::DepthEstimator, with the C progress callback (nonzero = cancel).
#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"

using namespace dvs::capi;

extern "C" {

dvs_status dvs_depth_estimator_create(dvs_context* context, const char* model, int32_t input_size, int32_t metric,
                                      dvs_depth_estimator** out) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_depth_estimator_create";
    require(out, call, "out");
    *out = nullptr;
    require(context, call, "context");
    require(model, call, "model");
    if (input_size < 0) throw dvs::UsageError(std::string(call) + ": input_size must be 0 (= 518) or in [14, 4096], got " + std::to_string(input_size));
    if (metric < -1 || metric > 1) throw dvs::UsageError(std::string(call) + ": metric must be -1 (the checkpoint's mode), 0 or 1, got " + std::to_string(metric));
    dvs::DepthModelOptions o;
    if (input_size) o.input_size = input_size;
    if (metric >= 0) o.metric = metric == 1;
    auto handle = std::make_unique<dvs_depth_estimator>();
    handle->estimator = std::make_unique<dvs::DepthEstimator>(*context->context, model, o);
    *out = handle.release();
  });
}

dvs_status dvs_depth_estimator_metric(const dvs_depth_estimator* estimator, int32_t* out) {
  return guarded(DVS_ERROR_FILE, [&] {
    require(estimator, "dvs_depth_estimator_metric", "estimator");
    require(out, "dvs_depth_estimator_metric", "out");
    *out = estimator->estimator->metric() ? 1 : 0;
  });
}

dvs_status dvs_depth_estimator_estimate(dvs_depth_estimator* estimator, const uint8_t* frames, int32_t count,
                                        int32_t height, int32_t width, float* out, dvs_progress_fn progress, void* user) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_depth_estimator_estimate";
    require(estimator, call, "estimator");
    require(frames, call, "frames");
    require(out, call, "out");
    check_clip_size(count, height, width, call);
    const dvs::HostView in{const_cast<uint8_t*>(frames), dvs::ElementType::u8, {count, height, width, 3}};
    const dvs::HostView o{out, dvs::ElementType::f32, {count, height, width}};
    CProgress p{progress, user};
    estimator->estimator->estimate(in, o, p.fn(), p.cancelled());
  });
}

dvs_status dvs_depth_estimator_estimate_device(dvs_depth_estimator* estimator, dvs_buffer_range frames, int32_t count,
                                               int32_t height, int32_t width, dvs_buffer_range out,
                                               dvs_progress_fn progress, void* user) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_depth_estimator_estimate_device";
    require(estimator, call, "estimator");
    check_clip_size(count, height, width, call);
    const dvs::DeviceBufferView in{frames.buffer, frames.offset, dvs::ElementType::u8, {count, height, width, 3}};
    const dvs::DeviceBufferView o{out.buffer, out.offset, dvs::ElementType::f32, {count, height, width}};
    CProgress p{progress, user};
    estimator->estimator->estimate(in, o, p.fn(), p.cancelled());
  });
}

dvs_status dvs_depth_estimator_destroy(dvs_depth_estimator* estimator) {
  return guarded(DVS_ERROR_DEVICE, [&] { delete estimator; });
}

}  // extern "C"
