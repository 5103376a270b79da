// Must compile (tests/public_api/check_views_constness.cmake): a call's inputs take const memory (issue 34 §2.11), in
// each form an application writes them.
#include <dvs/clip_run.hpp>
#include <dvs/depth_file.hpp>
#include <dvs/depth_frames.hpp>
#include <dvs/scene.hpp>

#include <vector>

void inputs(dvs::Context& ctx, dvs::DepthEstimator& estimator, const std::vector<uint8_t>& rgb,
            const std::vector<float>& depth, std::vector<float>& disparity) {
  dvs::PointCloudScene scene(ctx, {rgb.data(), dvs::ElementType::u8, {4, 4, 3}},
                             {depth.data(), dvs::ElementType::f32, {4, 4}}, dvs::CameraIntrinsics::dvs_default(4, 4));
  const dvs::ConstHostView named{depth.data(), dvs::ElementType::f32, {1, 4, 4}};
  dvs::load_depth_frame(named, 0, 4, 4);
  estimator.estimate({rgb.data(), dvs::ElementType::u8, {1, 4, 4, 3}},
                     dvs::HostView{disparity.data(), dvs::ElementType::f32, {1, 4, 4}});
  dvs::ClipView clip;
  clip.frames = {rgb.data(), dvs::ElementType::u8, {1, 4, 4, 3}};
  clip.depth = named;
  std::vector<float> writable(16);
  clip.depth = dvs::HostView{writable.data(), dvs::ElementType::f32, {1, 4, 4}};  // a writable view is an input too
}
