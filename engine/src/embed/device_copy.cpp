#include "embed/device_copy.hpp"

#include "dvs/error.hpp"
#include "vk/check.hpp"

namespace dvs::embed {
namespace {

DType dtype_of(ElementType t) { return t == ElementType::f32 ? DType::f32 : DType::u8; }

void pipeline_barrier(VkCommandBuffer cmd, VkPipelineStageFlags src, VkPipelineStageFlags dst,
                      const VkBufferMemoryBarrier& barrier) {
  vkCmdPipelineBarrier(cmd, src, dst, 0, 0, nullptr, 1, &barrier, 0, nullptr);
}

// The copy holds the tensor's storage until it has run.
uint64_t keeping(vk::Context& ctx, uint64_t ticket, const Tensor& keep) {
  ctx.release_after(ticket, [keep]() {});
  return ticket;
}

}  // namespace

VkBufferMemoryBarrier buffer_barrier(VkBuffer buffer, VkDeviceSize offset, VkDeviceSize size, VkAccessFlags src,
                                     VkAccessFlags dst) {
  VkBufferMemoryBarrier b{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
  b.srcAccessMask = src;
  b.dstAccessMask = dst;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.buffer = buffer;
  b.offset = offset;
  b.size = size;
  return b;
}

void check_view_fits(vk::Context& ctx, const DeviceBufferView& view, ElementType type, const std::vector<int64_t>& shape,
                     const std::string& what) {
  const std::string head = "The device buffer given for " + what + " (" + view.describe() + ")";
  if (!view.buffer)
    throw Error(head + " has no VkBuffer (VK_NULL_HANDLE): pass a buffer of the context's device.",
                ErrorKind::invalid_argument);
  if (view.offset % 4 != 0)
    throw Error(head + " starts at offset " + std::to_string(view.offset) + ", which is not a multiple of 4.",
                ErrorKind::invalid_argument);
  if (view.type != type || view.shape != shape)
    throw Error(head + " does not match what dvs has there, " + DeviceBufferView{VK_NULL_HANDLE, 0, type, shape}.describe() +
                ": give a view of that element type and shape.", ErrorKind::invalid_argument);
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(ctx.device(), view.buffer, &req);  // at least the buffer's size
  if (view.offset + view.bytes() > req.size)
    throw Error(head + " needs bytes " + std::to_string(view.offset) + ".." + std::to_string(view.offset + view.bytes()) +
                " but the buffer holds at most " + std::to_string(req.size) + ".", ErrorKind::invalid_argument);
}

void check_view_fits(vk::Context& ctx, const DeviceBufferView& view, const Tensor& tensor, const std::string& what) {
  check_view_fits(ctx, view, tensor.dtype() == DType::u8 ? ElementType::u8 : ElementType::f32, tensor.shape(), what);
  if (dtype_of(view.type) != tensor.dtype())  // a tensor of another element type than f32/u8
    throw Error("internal: " + what + ": dvs holds " + tensor.describe() + " there", ErrorKind::internal);
}

HostTensor fetch_view(vk::Context& ctx, const DeviceBufferView& from, const std::string& what) {
  const Tensor t = Tensor::empty(ctx, from.shape, dtype_of(from.type), what + " from the application");
  ctx.wait(copy_to_tensor(ctx, from, t, what));
  return t.download(ctx);
}

void record_copy_to_tensor(VkCommandBuffer cmd, const DeviceBufferView& from, const Tensor& to) {
  const vk::BufferView& t = to.buffer();
  const VkDeviceSize bytes = to.bytes();
  // The application's writes (on its queue, ordered by a semaphore or by submission order, or on the host) and
  // dvs's earlier use of the tensor come before the copy.
  pipeline_barrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                   buffer_barrier(from.buffer, from.offset, bytes, VK_ACCESS_MEMORY_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT,
                                  VK_ACCESS_TRANSFER_READ_BIT));
  pipeline_barrier(cmd, kDvsStages, VK_PIPELINE_STAGE_TRANSFER_BIT,
                   buffer_barrier(t.buffer, t.offset, bytes, kDvsWrites, VK_ACCESS_TRANSFER_WRITE_BIT));
  VkBufferCopy region{from.offset, t.offset, bytes};
  vkCmdCopyBuffer(cmd, from.buffer, t.buffer, 1, &region);
  // dvs's later work reads what the copy wrote.
  pipeline_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, kDvsStages,
                   buffer_barrier(t.buffer, t.offset, bytes, VK_ACCESS_TRANSFER_WRITE_BIT, kDvsAccesses));
}

void record_copy_from_tensor(VkCommandBuffer cmd, const Tensor& from, const DeviceBufferView& to) {
  const vk::BufferView& t = from.buffer();
  const VkDeviceSize bytes = from.bytes();
  // dvs's writes of the tensor, and the application's earlier use of its buffer, come before the copy.
  pipeline_barrier(cmd, kDvsStages, VK_PIPELINE_STAGE_TRANSFER_BIT,
                   buffer_barrier(t.buffer, t.offset, bytes, kDvsWrites, VK_ACCESS_TRANSFER_READ_BIT));
  pipeline_barrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                   buffer_barrier(to.buffer, to.offset, bytes, VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT,
                                  VK_ACCESS_TRANSFER_WRITE_BIT));
  VkBufferCopy region{t.offset, to.offset, bytes};
  vkCmdCopyBuffer(cmd, t.buffer, to.buffer, 1, &region);
  // The application reads the result on the host or on the device once the ticket is reached; dvs's later writes
  // of the tensor wait for the copy's read.
  pipeline_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                   buffer_barrier(to.buffer, to.offset, bytes, VK_ACCESS_TRANSFER_WRITE_BIT,
                                  VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_HOST_READ_BIT));
  pipeline_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, kDvsStages,
                   buffer_barrier(t.buffer, t.offset, bytes, 0, kDvsWrites));
}

uint64_t submit_recorded(vk::Context& ctx, const std::function<void(VkCommandBuffer)>& record) {
  VkCommandBuffer cmd = ctx.allocate_command_buffer();
  try {
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkBeginCommandBuffer(cmd, &bi));
    record(cmd);
    VK_CHECK(vkEndCommandBuffer(cmd));
  } catch (...) {  // never submitted: the context would not free it
    vkFreeCommandBuffers(ctx.device(), ctx.command_pool(), 1, &cmd);
    throw;
  }
  return ctx.submit(cmd);  // the context frees cmd once it has run
}

uint64_t copy_to_tensor(vk::Context& ctx, const DeviceBufferView& from, const Tensor& to, const std::string& what) {
  check_view_fits(ctx, from, to, what);
  return keeping(ctx, submit_recorded(ctx, [&](VkCommandBuffer cmd) { record_copy_to_tensor(cmd, from, to); }), to);
}

uint64_t copy_from_tensor(vk::Context& ctx, const Tensor& from, const DeviceBufferView& to, const std::string& what) {
  check_view_fits(ctx, to, from, what);
  return keeping(ctx, submit_recorded(ctx, [&](VkCommandBuffer cmd) { record_copy_from_tensor(cmd, from, to); }), from);
}

}  // namespace dvs::embed
