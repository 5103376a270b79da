// Copies between an application's VkBuffer (dvs::DeviceBufferView) and a dvs Tensor on the same device, without a
// round trip through the host. The recorded copy carries its own buffer barriers: against dvs's earlier and later
// work on the tensor, against the application's earlier use of its buffer, and (for copies into the application's
// buffer) towards host reads once the ticket is reached. The application orders its own use of the buffer with the
// context's timeline (wait for the ticket) and wait_before_next (dvs waits for the application). The buffer must be
// usable on dvs's queue family: the same family, or created with VK_SHARING_MODE_CONCURRENT.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dvs/views.hpp"
#include "io/host_tensor.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"

namespace dvs::embed {

// dvs's own work on a tensor (compute shaders and transfers): the stages and accesses the copies' barriers order
// against.
constexpr VkPipelineStageFlags kDvsStages = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
constexpr VkAccessFlags kDvsWrites = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
constexpr VkAccessFlags kDvsAccesses =
    VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;

// A barrier on bytes [offset, offset + size) of `buffer`, no queue-family transfer.
VkBufferMemoryBarrier buffer_barrier(VkBuffer buffer, VkDeviceSize offset, VkDeviceSize size, VkAccessFlags src,
                                     VkAccessFlags dst);

// Throws dvs::Error naming `what` ("the depth output") when `view` cannot stand for `tensor`: no buffer, an
// offset that is not a multiple of 4, another element type or shape, or a range past the buffer's end.
void check_view_fits(vk::Context& ctx, const DeviceBufferView& view, const Tensor& tensor, const std::string& what);

// The same check against an element type and shape, before the tensor exists (a run's result views, checked before
// any work).
void check_view_fits(vk::Context& ctx, const DeviceBufferView& view, ElementType type, const std::vector<int64_t>& shape,
                     const std::string& what);

// The view's elements brought to the host: copied into a dvs tensor of the view's shape, waited for, downloaded.
HostTensor fetch_view(vk::Context& ctx, const DeviceBufferView& from, const std::string& what);

// Record the copy into `cmd` (for callers that put it in a larger command buffer); check_view_fits first.
void record_copy_to_tensor(VkCommandBuffer cmd, const DeviceBufferView& from, const Tensor& to);
void record_copy_from_tensor(VkCommandBuffer cmd, const Tensor& from, const DeviceBufferView& to);

// `record` into a one-time command buffer of its own, submitted without a wait; returns its ticket (the context
// frees the command buffer once it has run). For copies the caller records itself (several into one submission).
uint64_t submit_recorded(vk::Context& ctx, const std::function<void(VkCommandBuffer)>& record);

// Check, record and submit on their own, without waiting: return the ticket (a value of ctx.timeline()). The
// tensor's storage is kept alive until the ticket is reached; the application's buffer must stay valid until then.
uint64_t copy_to_tensor(vk::Context& ctx, const DeviceBufferView& from, const Tensor& to, const std::string& what);
uint64_t copy_from_tensor(vk::Context& ctx, const Tensor& from, const DeviceBufferView& to, const std::string& what);

}  // namespace dvs::embed
