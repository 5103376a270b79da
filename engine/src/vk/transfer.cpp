#include "vk/transfer.hpp"

#include <algorithm>
#include <cstring>

#include "vk/check.hpp"
#include "vk/context.hpp"

namespace dvs::vk {

Transfer::Transfer(Context& ctx) : ctx_(ctx) {
  cmd_ = ctx.allocate_command_buffer();
  ctx.name_object(VK_OBJECT_TYPE_COMMAND_BUFFER, uint64_t(cmd_), "transfer");
}

Transfer::~Transfer() {
  if (cmd_) vkFreeCommandBuffers(ctx_.device(), ctx_.command_pool(), 1, &cmd_);
}

void Transfer::run(void (*record)(VkCommandBuffer, void*), void* user) {
  VK_CHECK(vkResetCommandBuffer(cmd_, 0));
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_CHECK(vkBeginCommandBuffer(cmd_, &bi));
  // Earlier compute work must be visible to the copy and the copy to later host reads / compute.
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  // HOST_WRITE needs the HOST stage named: ALL_COMMANDS does not include it (newer validation layers say so).
  vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                       VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &mb, 0, nullptr, 0, nullptr);
  record(cmd_, user);
  mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT | VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       0, 1, &mb, 0, nullptr, 0, nullptr);
  VK_CHECK(vkEndCommandBuffer(cmd_));
  ctx_.submit_and_wait(cmd_);
}

namespace {
struct CopyArgs {
  VkBuffer src, dst;
  VkBufferCopy region;
};
void record_copy(VkCommandBuffer cmd, void* user) {
  auto* a = static_cast<CopyArgs*>(user);
  vkCmdCopyBuffer(cmd, a->src, a->dst, 1, &a->region);
}
void record_fill(VkCommandBuffer cmd, void* user) {
  auto* v = static_cast<BufferView*>(user);
  vkCmdFillBuffer(cmd, v->buffer, v->offset, (v->size + 3) / 4 * 4, 0);
}
}  // namespace

size_t Transfer::staging_bytes() const {
  return size_t(std::min<VkDeviceSize>(kStagingBytes, ctx_.allocator().max_allocation() / 16 * 4));
}

void Transfer::upload(const BufferView& dst, const void* src, size_t bytes) {
  if (bytes > dst.size) throw Error("internal: upload of " + std::to_string(bytes) + " bytes into a smaller buffer");
  if (dst.mapped && !force_staging_) {
    std::memcpy(dst.mapped, src, bytes);
    return;
  }
  if (!upload_staging_.valid())
    upload_staging_ = ctx_.allocator().allocate(staging_bytes(), MemoryUse::upload, "upload staging");
  const uint8_t* p = static_cast<const uint8_t*>(src);
  for (size_t done = 0; done < bytes;) {
    size_t n = std::min<size_t>(bytes - done, upload_staging_.size());
    std::memcpy(upload_staging_.mapped(), p + done, n);
    CopyArgs a{upload_staging_.view().buffer, dst.buffer, {upload_staging_.view().offset, dst.offset + done, n}};
    run(record_copy, &a);
    done += n;
  }
}

void Transfer::download(const BufferView& src, void* dst, size_t bytes) {
  if (bytes > src.size) throw Error("internal: download of " + std::to_string(bytes) + " bytes from a smaller buffer");
  if (src.mapped && !force_staging_) {
    std::memcpy(dst, src.mapped, bytes);
    return;
  }
  if (!readback_staging_.valid())
    readback_staging_ = ctx_.allocator().allocate(staging_bytes(), MemoryUse::readback, "readback staging");
  uint8_t* p = static_cast<uint8_t*>(dst);
  for (size_t done = 0; done < bytes;) {
    size_t n = std::min<size_t>(bytes - done, readback_staging_.size());
    CopyArgs a{src.buffer, readback_staging_.view().buffer, {src.offset + done, readback_staging_.view().offset, n}};
    run(record_copy, &a);
    std::memcpy(p + done, readback_staging_.mapped(), n);
    done += n;
  }
}

void Transfer::copy(const BufferView& src, const BufferView& dst, size_t bytes) {
  if (bytes > src.size || bytes > dst.size) throw Error("internal: device copy larger than its buffers");
  CopyArgs a{src.buffer, dst.buffer, {src.offset, dst.offset, bytes}};
  run(record_copy, &a);
}

void Transfer::fill_zero(const BufferView& dst) {
  BufferView v = dst;
  run(record_fill, &v);
}

}  // namespace dvs::vk
