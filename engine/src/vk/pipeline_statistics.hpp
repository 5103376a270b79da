// A compute pipeline's compiled-code statistics through VK_KHR_pipeline_executable_properties (issue 35 C.1):
// what the driver reports per executable, e.g. NVIDIA's register count, spills and shared memory. Only for a
// pipeline created while PipelineCache::set_capture_statistics was on, on a device with the extension
// (caps.pipeline_executable_info); dvs-bench --filter gpu prints them for every kernel a case ran.
#pragma once
#include <string>
#include <vector>

#include "vk/pipeline.hpp"

namespace dvs::vk {

class Context;

struct PipelineStatistic {
  std::string executable;  // the executable's name (one per shader stage; compute pipelines have one)
  std::string name, description;
  std::string value;       // the driver's number as text (bool, signed, unsigned or float64)
};

// Empty when the pipeline was not created to capture them (or the device cannot).
std::vector<PipelineStatistic> pipeline_statistics(const Context& ctx, const Pipeline& p);

}  // namespace dvs::vk
