// The Video-Depth-Anything memory plan (models/vda/vda_memory.hpp) against what the model really holds: the weights
// exactly as uploaded, and one clip's activation peak bounded by the plan (and not wildly above it), at two sizes.
#include <gtest/gtest.h>

#include "models/vda/vda_memory.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_video.hpp"
#include "support/gpu.hpp"
#include "support/vda_pack.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

class VdaMemoryPlan : public test::GpuTest {};

TEST_F(VdaMemoryPlan, BoundsWhatAClipReallyHolds) {
  vk::Allocator& alloc = ctx().allocator();
  const uint64_t before = alloc.stats().bytes_in_use;
  VdaModel model = VdaModel::load(ctx(), test::vda_checkpoint_path());
  const uint64_t weights = alloc.stats().bytes_in_use - before;
  for (auto [frame_h, frame_w, input_size] : {std::tuple{48, 64, 42}, std::tuple{90, 160, 70}}) {
    HostTensor clip({40, frame_h, frame_w, 3}, DType::u8);
    for (int64_t i = 0; i < clip.numel(); ++i) clip.as<uint8_t>()[i] = uint8_t((i * 37) % 251);
    const VdaInputSize in = vda_input_size(frame_h, frame_w, input_size, model.config().patch_size);
    const VdaMemory plan = plan_vda_memory(model.config(), model.config().infer_len, in.height, in.width, frame_h, frame_w,
                                           VdaModel::kHeadMicroBatch, alloc.alignment());
    EXPECT_EQ(plan.weights, weights) << "the weights the plan counts are not what the model uploads";
    alloc.reset_peak();
    VdaVideoOptions o;
    o.input_size = input_size;
    vda_video_depth(model, clip, o);
    const uint64_t measured = alloc.stats().peak_bytes_in_use - before - weights;
    std::printf("  %dx%d input %lldx%lld: plan %llu B (%s), measured %llu B\n", frame_h, frame_w,
                static_cast<long long>(in.height), static_cast<long long>(in.width),
                static_cast<unsigned long long>(plan.activations), plan.peak_phase.c_str(),
                static_cast<unsigned long long>(measured));
    EXPECT_GE(plan.activations, measured) << "the plan is below the real peak";
    EXPECT_LE(plan.activations, 2 * measured) << "the plan is more than twice the real peak";
  }
}

}  // namespace
}  // namespace dvs
