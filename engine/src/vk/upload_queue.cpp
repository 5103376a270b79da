#include "vk/upload_queue.hpp"

#include <string>

#include "dvs/error.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"
#include "vk/timestamp_queries.hpp"

namespace dvs::vk {

UploadQueue::UploadQueue(Context& ctx) : ctx_(ctx) {
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = ctx.transfer_queue_family();
  VK_CHECK(vkCreateCommandPool(ctx.device(), &pci, nullptr, &pool_));
  VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
  type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
  VkSemaphoreCreateInfo sci{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  sci.pNext = &type;
  const VkResult r = vkCreateSemaphore(ctx.device(), &sci, nullptr, &timeline_);
  if (r != VK_SUCCESS) {
    vkDestroyCommandPool(ctx.device(), pool_, nullptr);
    VK_CHECK(r);
  }
}

UploadQueue::~UploadQueue() {
  VkSemaphoreWaitInfo wi{VK_STRUCTURE_TYPE_SEMAPHORE_WAIT_INFO};
  wi.semaphoreCount = 1;
  wi.pSemaphores = &timeline_;
  wi.pValues = &submitted_;
  if (submitted_ > 0) vkWaitSemaphores(ctx_.device(), &wi, UINT64_MAX);  // a lost device returns at once
  vkDestroySemaphore(ctx_.device(), timeline_, nullptr);
  vkDestroyCommandPool(ctx_.device(), pool_, nullptr);  // frees its command buffers
}

bool UploadQueue::on_compute_queue() const { return !ctx_.has_transfer_queue(); }

uint64_t UploadQueue::completed() const {
  uint64_t v = 0;
  VK_CHECK(vkGetSemaphoreCounterValue(ctx_.device(), timeline_, &v));
  return v;
}

void UploadQueue::wait(uint64_t value) {
  if (value > submitted_)
    throw Error("internal: UploadQueue::wait for upload " + std::to_string(value) + " of " + std::to_string(submitted_));
  if (value == 0) return;
  VkSemaphoreWaitInfo wi{VK_STRUCTURE_TYPE_SEMAPHORE_WAIT_INFO};
  wi.semaphoreCount = 1;
  wi.pSemaphores = &timeline_;
  wi.pValues = &value;
  VK_CHECK(vkWaitSemaphores(ctx_.device(), &wi, UINT64_MAX));
  recycle();
}

void UploadQueue::recycle() {
  const uint64_t done = completed();
  for (auto it = in_flight_.begin(); it != in_flight_.end();) {
    if (it->first <= done) {
      vkFreeCommandBuffers(ctx_.device(), pool_, 1, &it->second);
      it = in_flight_.erase(it);
    } else {
      ++it;
    }
  }
}

uint64_t UploadQueue::upload(const std::vector<Copy>& copies, uint64_t after, const TimestampQueries* stamps,
                             uint32_t first_query) {
  for (const Copy& c : copies)
    if (c.bytes > c.src.size || c.bytes > c.dst.size) throw Error("internal: UploadQueue::upload larger than its buffers");
  if (after > ctx_.submission_count())
    throw Error("internal: UploadQueue::upload after compute value " + std::to_string(after) + ", not submitted yet");
  recycle();
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VK_CHECK(vkAllocateCommandBuffers(ctx_.device(), &ai, &cmd));
  try {
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkBeginCommandBuffer(cmd, &bi));
    if (stamps) stamps->record(cmd, first_query, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    // The host wrote the source before this submission (a submission orders earlier host writes); the
    // semaphores order the copy with the compute on either side of it.
    for (const Copy& c : copies) {
      const VkBufferCopy region{c.src.offset, c.dst.offset, c.bytes};
      vkCmdCopyBuffer(cmd, c.src.buffer, c.dst.buffer, 1, &region);
    }
    if (stamps) stamps->record(cmd, first_query + 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    VK_CHECK(vkEndCommandBuffer(cmd));
    ctx_.submit_transfer(cmd, after, timeline_, submitted_ + 1);
  } catch (...) {
    vkFreeCommandBuffers(ctx_.device(), pool_, 1, &cmd);
    throw;
  }
  in_flight_.emplace_back(++submitted_, cmd);
  return submitted_;
}

}  // namespace dvs::vk
