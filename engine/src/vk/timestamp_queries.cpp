#include "vk/timestamp_queries.hpp"

#include <string>

#include "dvs/error.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"

namespace dvs::vk {

TimestampQueries::TimestampQueries(Context& ctx, uint32_t count) : ctx_(ctx), count_(count) {
  if (!ctx.caps().timestamps)
    throw Error("GPU timestamps: device '" + ctx.caps().name + "' has none on its compute queue");
  VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
  qi.queryCount = count;
  VK_CHECK(vkCreateQueryPool(ctx.device(), &qi, nullptr, &pool_));
}

TimestampQueries::~TimestampQueries() {
  if (last_mark_) ctx_.wait(last_mark_);
  vkDestroyQueryPool(ctx_.device(), pool_, nullptr);
}

void TimestampQueries::record(VkCommandBuffer cmd, uint32_t query, VkPipelineStageFlagBits stage) const {
  if (query >= count_)
    throw Error("internal: timestamp query " + std::to_string(query) + " of " + std::to_string(count_));
  vkCmdResetQueryPool(cmd, pool_, query, 1);
  vkCmdWriteTimestamp(cmd, stage, pool_, query);
}

void TimestampQueries::mark(uint32_t query) {
  VkCommandBuffer cmd = ctx_.allocate_command_buffer();
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_CHECK(vkBeginCommandBuffer(cmd, &bi));
  record(cmd, query, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
  VK_CHECK(vkEndCommandBuffer(cmd));
  last_mark_ = ctx_.submit(cmd);  // the context frees cmd once it has run
}

std::vector<double> TimestampQueries::read_ns(uint32_t first, uint32_t n) const {
  if (first + n > count_ || first + n < first)
    throw Error("internal: timestamp queries " + std::to_string(first) + "+" + std::to_string(n) + " of " +
                std::to_string(count_));
  std::vector<uint64_t> ticks(n);
  if (n) VK_CHECK(vkGetQueryPoolResults(ctx_.device(), pool_, first, n, ticks.size() * sizeof(uint64_t), ticks.data(),
                                        sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
  std::vector<double> ns(n);
  for (uint32_t i = 0; i < n; ++i) ns[i] = double(ticks[i]) * double(ctx_.caps().timestamp_period_ns);
  return ns;
}

}  // namespace dvs::vk
