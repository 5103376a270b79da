// dvs on the application's Vulkan device (issue 22, item 2). The test plays the application: it creates its own
// instance (validation layer with synchronization validation, and a messenger that records every message) and
// device, hands them to dvs::Context, runs dvs work on them and checks by value what the application sees: results
// in its buffers after waiting for dvs's ticket on the host or on its own queue, dvs waiting for the application's
// semaphore, its queue lock taken around every submission, and its device still working after dvs is gone.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <string>
#include <thread>
#include <vector>

#include "dvs/context.hpp"
#include "dvs/error.hpp"
#include "embed/device_copy.hpp"
#include "support/app_device.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"

namespace dvs {
namespace {

using App = test::AppDevice;
using test::AppFeatures;

ContextOptions no_disk_cache() {
  ContextOptions o;
  o.pipeline_cache_file = "-";
  return o;
}

// Values whose 2x + 1 is exact in fp32, different at every index.
std::vector<float> ramp(size_t n, float start) {
  std::vector<float> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = start + 0.5f * float(i);
  return v;
}

TEST(HostDevice, RunsDvsWorkOnTheApplicationsDeviceAndLeavesItUsable) {
  App app;
  const size_t n = 1000;
  const std::vector<float> x = ramp(n, -7.0f);
  {
    Context ctx(app.host(), no_disk_cache());
    EXPECT_FALSE(ctx.owns_device());
    ASSERT_NE(ctx.timeline(), VK_NULL_HANDLE);
    vk::Context& v = ctx.internal();
    EXPECT_EQ(v.device(), app.device);
    Tensor tx = Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, x), "x");
    Tensor ty = Tensor::empty(v, {int64_t(n)}, DType::f32, "y");
    vk::Recorder rec(v);
    rec.begin();
    ops::scale(rec, tx, ty, 2.0f, 1.0f);
    rec.end();
    rec.submit();
    const std::vector<float> y = ty.download(v).to_f32();
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(y[i], 2.0f * x[i] + 1.0f) << "element " << i;
    EXPECT_GT(ctx.submitted_value(), 0u);
    EXPECT_TRUE(ctx.wait(ctx.submitted_value(), 0));
    EXPECT_EQ(v.completed_value(), ctx.submitted_value());
  }
  // Every submission under the application's lock, in pairs (a lost unlock would also fail try_lock above).
  EXPECT_GE(app.locks, 1);
  EXPECT_EQ(app.locks, app.unlocks);

  // dvs is gone; the application's device, queue and pool still work.
  App::Buffer& a = app.buffer(64 * sizeof(float));
  App::Buffer& b = app.buffer(64 * sizeof(float));
  for (int i = 0; i < 64; ++i) a.f32()[i] = float(i * 3);
  app.copy_buffer(a.buffer, b.buffer, 64 * sizeof(float));
  for (int i = 0; i < 64; ++i) ASSERT_EQ(b.f32()[i], float(i * 3));
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, CopiesATensorIntoTheApplicationsBufferOrderedByTheTicket) {
  App app;
  const size_t n = 4096;
  const std::vector<float> first = ramp(n, 3.0f), second = ramp(n, -100.0f);
  {
    Context ctx(app.host(), no_disk_cache());
    vk::Context& v = ctx.internal();
    App::Buffer& out = app.buffer(n * sizeof(float));
    const DeviceBufferView view{out.buffer, 0, ElementType::f32, {int64_t(n)}};

    // Waited for on the host: the application reads the values once the ticket is reached.
    const uint64_t before = ctx.submitted_value();
    const uint64_t t1 = embed::copy_from_tensor(v, Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, first)), view,
                                                "the test's output");
    EXPECT_GT(t1, before);
    EXPECT_EQ(ctx.submitted_value(), t1);
    ASSERT_TRUE(ctx.wait(t1));
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(out.f32()[i], first[i]) << "element " << i;

    // Waited for on the application's queue: its copy waits for the ticket on dvs's timeline, nothing on the host.
    App::Buffer& mirror = app.buffer(n * sizeof(float));
    const uint64_t t2 = embed::copy_from_tensor(v, Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, second)),
                                                view, "the test's output");
    app.copy_buffer(out.buffer, mirror.buffer, n * sizeof(float), ctx.timeline(), t2);
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(mirror.f32()[i], second[i]) << "element " << i;
    EXPECT_TRUE(ctx.wait(t2));

    // dvs's compute result straight into the application's buffer, by value. (Synchronization validation does not
    // compare host-waited submissions; test_scene_device_memory.cpp checks the barriers across submissions that
    // are not host-waited.)
    Tensor x = Tensor::upload(v, HostTensor::from_f32({int64_t(n)}, first));
    Tensor y = Tensor::empty(v, {int64_t(n)}, DType::f32, "y");
    vk::Recorder rec(v);
    rec.begin();
    ops::scale(rec, x, y, 2.0f, 1.0f);
    rec.end();
    rec.submit();
    ASSERT_TRUE(ctx.wait(embed::copy_from_tensor(v, y, view, "the test's output")));
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(out.f32()[i], 2.0f * first[i] + 1.0f) << "element " << i;
  }
  EXPECT_EQ(app.locks, app.unlocks);
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, NextSubmissionWaitsForTheApplicationsSemaphore) {
  App app;
  const size_t n = 512;
  const std::vector<float> written_later = ramp(n, 11.0f);
  {
    Context ctx(app.host(), no_disk_cache());
    vk::Context& v = ctx.internal();
    App::Buffer& in = app.buffer(n * sizeof(float));  // zeros until the application writes it below
    VkSemaphore ready = app.timeline_semaphore();
    Tensor t = Tensor::zeros(v, {int64_t(n)}, DType::f32, "copy target");

    ctx.wait_before_next(ready, 1);
    const uint64_t ticket =
        embed::copy_to_tensor(v, {in.buffer, 0, ElementType::f32, {int64_t(n)}}, t, "the test's input");
    // Submitted, but held back by the application's semaphore.
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_FALSE(ctx.wait(ticket, 20'000'000)) << "dvs's copy ran before the application signalled";
    EXPECT_LT(v.completed_value(), ticket);

    // The application fills its buffer on the host, then signals.
    std::memcpy(in.data, written_later.data(), n * sizeof(float));
    VkSemaphoreSignalInfo signal{VK_STRUCTURE_TYPE_SEMAPHORE_SIGNAL_INFO};
    signal.semaphore = ready;
    signal.value = 1;
    ASSERT_EQ(vkSignalSemaphore(app.device, &signal), VK_SUCCESS);
    ASSERT_TRUE(ctx.wait(ticket));
    const std::vector<float> got = t.download(v).to_f32();
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(got[i], written_later[i]) << "element " << i;

    // The wait applied to one submission only: the next one runs at once.
    const uint64_t next = embed::copy_to_tensor(v, {in.buffer, 0, ElementType::f32, {int64_t(n)}}, t, "the input");
    EXPECT_TRUE(ctx.wait(next, 5'000'000'000ull));
  }
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, DeviceWithoutTimelineSemaphoreIsRefusedByName) {
  App app(AppFeatures{.timeline_semaphore = false});
  test::expect_error([&] { Context ctx(app.host(), no_disk_cache()); },
                     {"timelineSemaphore", "VkPhysicalDeviceVulkan12Features::timelineSemaphore = VK_TRUE"});
  // Every missing item at once: also a queue family without compute (an index past the last family).
  HostDevice bad = app.host();
  bad.queue_family = 99;
  bad.instance_api_version = VK_API_VERSION_1_1;
  test::expect_error([&] { Context ctx(bad, no_disk_cache()); },
                     {"timelineSemaphore", "VK_QUEUE_COMPUTE_BIT", "Vulkan 1.2", "instance_api_version"});
  // The memory model on without its device scope: dvs's device-scope atomics would be invalid.
  VkPhysicalDeviceVulkan12Features has12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 has{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &has12};
  vkGetPhysicalDeviceFeatures2(app.physical, &has);
  if (has12.vulkanMemoryModel) {
    App memory_model(AppFeatures{.memory_model_without_device_scope = true});
    test::expect_error([&] { Context ctx(memory_model.host(), no_disk_cache()); },
                       {"vulkanMemoryModelDeviceScope = VK_TRUE"});
    EXPECT_TRUE(memory_model.messages.empty()) << memory_model.first_message();
  }
  HostDevice none;
  test::expect_error([&] { Context ctx(none, no_disk_cache()); },
                     {"HostDevice::instance", "HostDevice::physical_device", "HostDevice::device", "HostDevice::queue"});
  // The refused device is the application's, untouched.
  App::Buffer& a = app.buffer(16 * sizeof(float));
  App::Buffer& b = app.buffer(16 * sizeof(float));
  for (int i = 0; i < 16; ++i) a.f32()[i] = float(i + 1);
  app.copy_buffer(a.buffer, b.buffer, 16 * sizeof(float));
  for (int i = 0; i < 16; ++i) ASSERT_EQ(b.f32()[i], float(i + 1));
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(HostDevice, UsesOnlyWhatTheApplicationEnabled) {
  const vk::DeviceCaps& offered = test::gpu().caps();  // dvs's own device enables all it can
  {
    App app;  // float16 off
    Context ctx(app.host(), no_disk_cache());
    EXPECT_FALSE(ctx.internal().caps().float16_arithmetic);
    EXPECT_FALSE(ctx.internal().caps().float32_atomic_add);  // VK_EXT_shader_atomic_float not enabled
    EXPECT_FALSE(ctx.internal().caps().cooperative_matrix);
    EXPECT_FALSE(ctx.internal().caps().subgroup_size_control);
  }
  if (offered.float16_arithmetic) {
    App app(AppFeatures{.float16 = true});
    Context ctx(app.host(), no_disk_cache());
    EXPECT_TRUE(ctx.internal().caps().float16_arithmetic);
  }
  const auto required = Context::required_features();
  EXPECT_NE(std::find(required.begin(), required.end(), "timelineSemaphore"), required.end());
  EXPECT_FALSE(Context::optional_features().empty());
}

TEST(HostDevice, DeviceViewsAreCheckedAndNamed) {
  App app;
  Context ctx(app.host(), no_disk_cache());
  vk::Context& v = ctx.internal();
  App::Buffer& small = app.buffer(1 * sizeof(float));
  Tensor t = Tensor::zeros(v, {4, 4}, DType::f32, "t");
  Tensor big = Tensor::zeros(v, {64, 64}, DType::f32, "big");
  const uint64_t before = ctx.submitted_value();  // the zero fills
  test::expect_error([&] { embed::copy_to_tensor(v, {small.buffer, 0, ElementType::f32, {16}}, t, "the frame"); },
                     {"the frame", "f32[16]", "f32[4x4]"});
  test::expect_error([&] { embed::copy_to_tensor(v, {small.buffer, 0, ElementType::u8, {4, 4}}, t, "the mask"); },
                     {"the mask", "u8[4x4]", "f32[4x4]"});
  test::expect_error([&] { embed::copy_to_tensor(v, {small.buffer, 2, ElementType::f32, {4, 4}}, t, "the depth"); },
                     {"the depth", "multiple of 4"});
  test::expect_error([&] { embed::copy_from_tensor(v, big, {small.buffer, 0, ElementType::f32, {64, 64}}, "the output"); },
                     {"the output", "at most"});
  test::expect_error([&] { embed::copy_from_tensor(v, t, {VK_NULL_HANDLE, 0, ElementType::f32, {4, 4}}, "the output"); },
                     {"the output", "VK_NULL_HANDLE"});
  EXPECT_EQ(ctx.submitted_value(), before) << "a refused copy was submitted";
  test::expect_error([&] { ctx.wait(before + 5); }, {std::to_string(before + 5), "never"});
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

// dvs's own device (what the rest of the suite uses) has the timeline too: tickets count submissions, and what
// release_after holds is released once its ticket is reached.
class OwnDeviceTimeline : public test::GpuTest {};

TEST_F(OwnDeviceTimeline, TicketsCountSubmissionsAndReleaseAfterRuns) {
  vk::Context& v = ctx();
  ASSERT_NE(v.timeline(), VK_NULL_HANDLE);
  const uint64_t before = v.submission_count();
  const std::vector<float> values{1, 2, 3};
  Tensor t = Tensor::upload(v, HostTensor::from_f32({3}, values));
  Tensor u = Tensor::zeros(v, {3}, DType::f32);
  VkCommandBuffer cmd = v.allocate_command_buffer();
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  vkBeginCommandBuffer(cmd, &bi);
  // As every command buffer dvs submits, this one starts with a barrier ordering it after the work before it (the
  // fill that zeroed u: without it, the copy's write raced that fill's, which the layer's QueueSubmit check reports).
  VkMemoryBarrier after_earlier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  after_earlier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT;
  after_earlier.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                       0, 1, &after_earlier, 0, nullptr, 0, nullptr);
  VkBufferCopy region{t.buffer().offset, u.buffer().offset, t.bytes()};
  vkCmdCopyBuffer(cmd, t.buffer().buffer, u.buffer().buffer, 1, &region);
  VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       0, 1, &to_host, 0, nullptr, 0, nullptr);
  vkEndCommandBuffer(cmd);
  const uint64_t ticket = v.submit(cmd);
  EXPECT_EQ(ticket, v.submission_count());
  EXPECT_GT(ticket, before);
  bool released = false;
  v.release_after(ticket, [&] { released = true; });
  ASSERT_TRUE(v.wait(ticket));
  EXPECT_TRUE(released);
  EXPECT_EQ(u.download(v).to_f32(), (std::vector<float>{1, 2, 3}));
}

}  // namespace
}  // namespace dvs
