// What an out-of-device-memory error in a stage of `dvs run` / `dvs invert` adds: the memory plan's figures for
// that stage on this device (the same plan `dvs plan --device` and the preflight make) and which option
// lowers them.
#pragma once
#include <string>

#include "dvs/pipeline.hpp"
#include "pipeline/memory_plan.hpp"
#include "vk/device_info.hpp"

namespace dvs {

// The plan request for a run on `dev`: the run's size and VAE tiling against the device's budget and limits.
pipeline::PlanRequest run_plan_request(const RunOptions& o, const vk::DeviceCaps& dev);

// "; dvs plan for this run on <device>: ... Try ..." for the run stage `stage` ("encode", "text", "invert",
// "sample", "decode", "depth", ...). Never throws: without a plan (unreadable configs, no device) it gives the
// generic advice.
std::string out_of_memory_advice(const RunOptions& o, const std::string& stage);

}  // namespace dvs
