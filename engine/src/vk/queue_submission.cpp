// vk::Context's submissions: one vkQueueSubmit per call, each signalling the context's timeline semaphore with
// the next value (its ticket), taking the application's queue lock around it, and waiting first for what
// wait_before_next asked. Blocking callers wait for their ticket on the timeline; asynchronous ones get it back.
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "dvs/error.hpp"
#include "io/injected_faults.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"

namespace dvs::vk {
namespace {

// dvs's own lock of a VkQueue, one per queue in the process: contexts made on one HostDevice share its queue, and
// Vulkan requires vkQueueSubmit on one queue to be externally synchronised, whether or not the application gave a
// lock of its own (taken inside this one).
std::mutex& queue_mutex(VkQueue queue) {
  static std::mutex registry_mutex;
  static std::map<VkQueue, std::unique_ptr<std::mutex>> registry;  // a few entries; never removed
  std::lock_guard<std::mutex> lock(registry_mutex);
  std::unique_ptr<std::mutex>& m = registry[queue];
  if (!m) m = std::make_unique<std::mutex>();
  return *m;
}

// The application's queue lock held for one scope (no-op without one).
class QueueLock {
 public:
  QueueLock(const std::function<void()>& lock, const std::function<void()>& unlock) : unlock_(unlock) {
    if (lock) lock();
  }
  ~QueueLock() {
    if (unlock_) unlock_();
  }
  QueueLock(const QueueLock&) = delete;
  QueueLock& operator=(const QueueLock&) = delete;

 private:
  const std::function<void()>& unlock_;
};

}  // namespace

uint64_t Context::queue_submit(VkCommandBuffer cmd) {
  // DVS_FAULTS=submit=N: this submission reports a lost device (io/injected_faults.hpp).
  if (faults::fail_now(faults::Kind::submit, "vkQueueSubmit"))
    throw_vk_error(VK_ERROR_DEVICE_LOST, "vkQueueSubmit", __FILE__, __LINE__);
  const uint64_t ticket = submissions_ + 1;
  std::vector<VkSemaphore> wait_semaphores;
  std::vector<uint64_t> wait_values;
  std::vector<VkPipelineStageFlags> wait_stages;
  for (const auto& [semaphore, value] : waits_before_next_) {
    wait_semaphores.push_back(semaphore);
    wait_values.push_back(value);
    wait_stages.push_back(VK_PIPELINE_STAGE_ALL_COMMANDS_BIT);
  }
  VkTimelineSemaphoreSubmitInfo timeline_info{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
  timeline_info.waitSemaphoreValueCount = uint32_t(wait_values.size());
  timeline_info.pWaitSemaphoreValues = wait_values.data();
  timeline_info.signalSemaphoreValueCount = 1;
  timeline_info.pSignalSemaphoreValues = &ticket;
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.pNext = &timeline_info;
  si.waitSemaphoreCount = uint32_t(wait_semaphores.size());
  si.pWaitSemaphores = wait_semaphores.data();
  si.pWaitDstStageMask = wait_stages.data();
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  si.signalSemaphoreCount = 1;
  si.pSignalSemaphores = &timeline_;
  {
    std::lock_guard<std::mutex> own(queue_mutex(queue_));
    QueueLock lock(lock_queue_, unlock_queue_);
    VK_CHECK(vkQueueSubmit(queue_, 1, &si, VK_NULL_HANDLE));
  }
  waits_before_next_.clear();
  submissions_ = ticket;
  return ticket;
}

void Context::submit_and_wait(VkCommandBuffer cmd) { wait(queue_submit(cmd)); }

void Context::submit_transfer(VkCommandBuffer cmd, uint64_t after, VkSemaphore semaphore, uint64_t value) {
  if (faults::fail_now(faults::Kind::submit, "vkQueueSubmit"))
    throw_vk_error(VK_ERROR_DEVICE_LOST, "vkQueueSubmit", __FILE__, __LINE__);
  const VkPipelineStageFlags stage = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
  VkTimelineSemaphoreSubmitInfo timeline_info{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
  timeline_info.waitSemaphoreValueCount = 1;
  timeline_info.pWaitSemaphoreValues = &after;
  timeline_info.signalSemaphoreValueCount = 1;
  timeline_info.pSignalSemaphoreValues = &value;
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.pNext = &timeline_info;
  si.waitSemaphoreCount = 1;
  si.pWaitSemaphores = &timeline_;
  si.pWaitDstStageMask = &stage;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  si.signalSemaphoreCount = 1;
  si.pSignalSemaphores = &semaphore;
  // The compute queue itself where the device has no transfer family: the application's lock applies then; dvs's
  // own lock of the queue always (contexts on one HostDevice share it).
  const bool shared = transfer_queue_ == queue_;
  static const std::function<void()> none;
  std::lock_guard<std::mutex> own(queue_mutex(transfer_queue_));
  QueueLock lock(shared ? lock_queue_ : none, shared ? unlock_queue_ : none);
  VK_CHECK(vkQueueSubmit(transfer_queue_, 1, &si, VK_NULL_HANDLE));
}

uint64_t Context::submit(VkCommandBuffer cmd) {
  uint64_t ticket = 0;
  try {
    ticket = queue_submit(cmd);
  } catch (...) {
    vkFreeCommandBuffers(device_, command_pool_, 1, &cmd);  // taken by submit: never submitted, free it now
    throw;
  }
  release_after(ticket, [this, cmd]() mutable { vkFreeCommandBuffers(device_, command_pool_, 1, &cmd); });
  return ticket;
}

void Context::drain_shared_queue() {
  if (!queue_) return;
  std::lock_guard<std::mutex> own(queue_mutex(queue_));
  QueueLock lock(lock_queue_, unlock_queue_);
  vkQueueWaitIdle(queue_);  // a lost device returns at once: nothing left to drain
}

uint64_t Context::completed_value() const {
  uint64_t value = 0;
  VK_CHECK(vkGetSemaphoreCounterValue(device_, timeline_, &value));
  return value;
}

bool Context::wait(uint64_t ticket, uint64_t timeout_ns) {
  if (ticket > submissions_)
    throw Error("Waiting for timeline value " + std::to_string(ticket) + " of dvs's context, but only " +
                    std::to_string(submissions_) + " submissions were made: it would never be reached (wait for a "
                "ticket a dvs call returned).",
                ErrorKind::invalid_argument);
  VkSemaphoreWaitInfo wi{VK_STRUCTURE_TYPE_SEMAPHORE_WAIT_INFO};
  wi.semaphoreCount = 1;
  wi.pSemaphores = &timeline_;
  wi.pValues = &ticket;
  const VkResult r = vkWaitSemaphores(device_, &wi, timeout_ns);
  if (r == VK_TIMEOUT) return false;
  VK_CHECK(r);
  release_reached();
  return true;
}

void Context::release_after(uint64_t ticket, std::function<void()> release) {
  pending_releases_.emplace_back(ticket, std::move(release));
  release_reached();
}

void Context::release_reached() {
  if (pending_releases_.empty()) return;
  const uint64_t reached = completed_value();
  std::vector<std::function<void()>> due;
  for (auto it = pending_releases_.begin(); it != pending_releases_.end();) {
    if (it->first <= reached) {
      due.push_back(std::move(it->second));
      it = pending_releases_.erase(it);
    } else {
      ++it;
    }
  }
  for (auto& action : due) action();
}

void Context::wait_before_next(VkSemaphore semaphore, uint64_t value) {
  if (!semaphore)
    throw Error("wait_before_next: the semaphore is VK_NULL_HANDLE (pass a timeline semaphore of the application's "
                "device)",
                ErrorKind::invalid_argument);
  waits_before_next_.emplace_back(semaphore, value);
}

}  // namespace dvs::vk
