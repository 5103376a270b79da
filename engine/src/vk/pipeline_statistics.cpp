#include "vk/pipeline_statistics.hpp"

#include <sstream>

#include "vk/check.hpp"
#include "vk/context.hpp"

namespace dvs::vk {
namespace {

std::string value_text(const VkPipelineExecutableStatisticKHR& s) {
  std::ostringstream o;
  switch (s.format) {
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR: o << (s.value.b32 ? "true" : "false"); break;
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR: o << s.value.i64; break;
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR: o << s.value.u64; break;
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_FLOAT64_KHR: o << s.value.f64; break;
    default: o << "?"; break;
  }
  return o.str();
}

}  // namespace

std::vector<PipelineStatistic> pipeline_statistics(const Context& ctx, const Pipeline& p) {
  std::vector<PipelineStatistic> out;
  if (!p.statistics_captured) return out;
  VkDevice dev = ctx.device();
  auto executables = reinterpret_cast<PFN_vkGetPipelineExecutablePropertiesKHR>(
      vkGetDeviceProcAddr(dev, "vkGetPipelineExecutablePropertiesKHR"));
  auto statistics = reinterpret_cast<PFN_vkGetPipelineExecutableStatisticsKHR>(
      vkGetDeviceProcAddr(dev, "vkGetPipelineExecutableStatisticsKHR"));
  if (!executables || !statistics) return out;
  VkPipelineInfoKHR info{VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR};
  info.pipeline = p.pipeline;
  uint32_t n = 0;
  VK_CHECK(executables(dev, &info, &n, nullptr));
  std::vector<VkPipelineExecutablePropertiesKHR> props(n, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR});
  VK_CHECK(executables(dev, &info, &n, props.data()));
  for (uint32_t e = 0; e < n; ++e) {
    VkPipelineExecutableInfoKHR ei{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR};
    ei.pipeline = p.pipeline;
    ei.executableIndex = e;
    uint32_t m = 0;
    VK_CHECK(statistics(dev, &ei, &m, nullptr));
    std::vector<VkPipelineExecutableStatisticKHR> stats(m, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR});
    VK_CHECK(statistics(dev, &ei, &m, stats.data()));
    for (uint32_t i = 0; i < m; ++i)
      out.push_back({props[e].name, stats[i].name, stats[i].description, value_text(stats[i])});
  }
  return out;
}

}  // namespace dvs::vk
